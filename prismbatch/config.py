"""Every number that sets what prismbatch accepts and how it decides, in one place.

Tolerances and thresholds are named here and documented once; the modules
that use them import them from here.
"""

#: Largest magnitude accepted for a position coordinate or a polygon's centre
#: (in the prism's local frame), and largest polygon radius. Inside this range
#: every product the kernels form stays finite (squares up to ~1e202), so the
#: tolerance contract holds; outside it a clear ValueError is raised once per
#: batch, never a wrong answer. Rescale your units to stay inside it.
MAX_MAGNITUDE = 1e100

#: Smallest polygon radius (about its centroid) accepted by the kernels: below
#: it, squared lengths underflow. :class:`~prismbatch.Prism` itself accepts any
#: finite convex polygon; :func:`~prismbatch.collide` checks this range.
MIN_RADIUS = 1e-100
