"""prismbatch: batched collision detection between convex semi-infinite prisms.

Implements the projection method of "Efficient Collision Detection and Detach
Control for Convex Prisms in Precision Manipulation" as parallel Numba kernels
behind a vectorised NumPy API.

>>> import prismbatch as pb
>>> a = pb.Prism.regular(5, 2.0)
"""

from .collide import CASES, Collider, CollisionResult, collide
from .shapes import Prism, PrismSet

__all__ = ["Prism", "PrismSet", "collide", "Collider", "CollisionResult", "CASES"]
__version__ = "0.1.0"
