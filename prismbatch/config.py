"""Every number that sets what prismbatch accepts and how it decides, in one place.

Tolerances and thresholds are named here and documented once; the modules
that use them import them from here.
"""

import numpy as np

#: Default relative tolerance per dtype. The absolute tolerance of a pair is
#: ``atol + rtol * (R_a + R_b + |c_b - c_a|) + 4 eps (|c_a| + |c_b|) + 8 eps (|k_a|_1 + |k_b|_1)``
#: (bounding radii of the end faces about their centres, the distance between the
#: centres, and rounding floors for positions far from the world origin and for
#: end faces far from their own local origins, k the centres in the local frames).
DEFAULT_RTOL = {np.dtype(np.float64): 1e-9, np.dtype(np.float32): 1e-5}

#: ``collide`` decides at ``tol + ROUNDING_ALLOWANCE * eps * (R_a + R_b + |c_b - c_a|_1 + |k_a|_1 + |k_b|_1)``,
#: not at tol: the relative pose and the planar gaps it computes from the poses carry rounding of about
#: eps S, and an adversarial run found certified gaps up to 2.3e-7 tol under tol (float64 defaults, about
#: 1 eps S) computed above it and missed; the end-face centres k are stored in the working precision, so in
#: float32 they move the polygons by up to ``eps |k| / 2`` (gaps of 0.971 tol missed with ``|k|`` of 1e2 to 1e4).
#: With the allowance every pair within tol is a hit; a hit may then be up to sqrt(2) times the allowance
#: farther apart (the README's Tolerance section).
ROUNDING_ALLOWANCE = 4.0

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

#: The same two bounds for float32 compute (largest float32 ~3.4e38, smallest
#: normal ~1.2e-38): products of up to three lengths stay finite and normal.
MAX_MAGNITUDE_F32 = 1e12
MIN_RADIUS_F32 = 1e-12

#: Thinnest outline accepted, relative to the polygon's size (its largest
#: edge coordinate): shorter edges and smaller areas (twice the area, over
#: the size squared) are outside the range the kernels were verified on.
MIN_RELATIVE_EDGE = 1e-14
MIN_RELATIVE_AREA = 1e-13

#: Largest relative tolerance accepted (a pair's tolerance then stays below
#: the scene's own size, and finite).
MAX_RTOL = 1.0

#: Most vertices :meth:`Prism.regular` builds (memory: ~240 bytes a vertex
#: once the kernels' tables are built).
MAX_VERTICES = 10_000_000

#: The lab's LP reference (:func:`prismbatch.lab.exact.margin_lp`) is trusted
#: to about this fraction of the scene size S; a pair whose LP margin lies
#: within ``max(tol, LP_TRUST_RTOL * S)`` of zero is in the touching band,
#: where only the exact reference decides (:func:`prismbatch.lab.exact.lp_trust_band`).
LP_TRUST_RTOL = 1e-7

#: (smallest radius, largest magnitude) by compute dtype name.
SUPPORTED_RANGE = {"float64": (MIN_RADIUS, MAX_MAGNITUDE), "float32": (MIN_RADIUS_F32, MAX_MAGNITUDE_F32)}

#: :func:`~prismbatch.control.detach` refuses a "contact" that lies outside a
#: by more than its tol plus this times a's end-face radius (plus the rounding
#: of the point's coordinates): far looser than any contact :func:`collide`
#: returns (within twice its pair tolerance of both bodies), so only points
#: that are not contacts at all are refused.
NOT_A_CONTACT_RTOL = 1e-3
