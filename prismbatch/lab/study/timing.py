"""The study's first calls: compile or cache load of each prismbatch path.

The generic timing helpers are in :mod:`prismbatch.lab.timing`.
"""

from __future__ import annotations

import os

import numpy as np

from ...collide import Collider
from ...shapes import Prism
from ..timing import seconds_of
from .constants import RADIUS_A, RADIUS_B


def compile_times():
    """First call of each prismbatch path on a tiny scene (compile or cache load)."""
    # The kernels module tells whether a kernel was compiled in this process before the first call.
    from ..._kernels import batch as kernels
    from ..._kernels import one_pair

    a, b = Prism.regular(5, RADIUS_A), Prism.regular(6, RADIUS_B)
    col = Collider(a, b)
    pa = np.zeros((4, 3))
    ra = np.broadcast_to(np.diag([1.0, -1.0, -1.0]), (4, 3, 3)).copy()
    pb_ = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [5.0, 0.0, 0.0], [1.0, 1.0, -0.5]])
    rb = np.broadcast_to(np.eye(3), (4, 3, 3)).copy()
    dispatchers = {
        "collide_pair": one_pair.collide_pair[np.dtype(np.float64)],
        "collide_serial": kernels.collide_serial,
        "collide_parallel": kernels.collide_parallel,
    }
    loaded = {name: bool(d.signatures) for name, d in dispatchers.items()}
    out = {
        "collide_pair_s": seconds_of(lambda: col.collide_pair(pa[0], ra[0], pb_[0], rb[0])),
        "collide_serial_s": seconds_of(lambda: col.collide(pa, ra, pb_, rb, parallel=False)),
        "collide_parallel_s": seconds_of(lambda: col.collide(pa, ra, pb_, rb, parallel=True)),
        # The same call again: what a warm call costs, to read the above against.
        "second_serial_call_s": seconds_of(lambda: col.collide(pa, ra, pb_, rb, parallel=False)),
    }
    out["already_compiled_in_process"] = loaded
    out["numba_cache_dir"] = os.environ.get("NUMBA_CACHE_DIR") or "(default: next to the sources)"
    return out
