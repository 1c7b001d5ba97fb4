"""prismbatch: batched collision detection between convex semi-infinite prisms.

Implements the projection method of "Efficient Collision Detection and Detach
Control for Convex Prisms in Precision Manipulation" as parallel Numba kernels
behind a vectorised NumPy API.

>>> import prismbatch as pb
>>> a = pb.Prism.regular(5, 2.0)
"""

from importlib.metadata import PackageNotFoundError, version

from .collide import CASES, Collider, CollisionResult, collide
from .distance import DistanceResult, distance
from .motion import TimeOfImpactResult, time_of_impact
from .probability import ProbabilityResult, collision_probability
from .shapes import Prism, PrismSet

__all__ = [
    "Prism",
    "PrismSet",
    "collide",
    "distance",
    "time_of_impact",
    "collision_probability",
    "Collider",
    "CollisionResult",
    "DistanceResult",
    "TimeOfImpactResult",
    "ProbabilityResult",
    "CASES",
]

try:  # the one place the version lives is pyproject.toml
    __version__ = version("prismbatch")
except PackageNotFoundError:  # run from a source tree that was never installed
    __version__ = "0+unknown"
