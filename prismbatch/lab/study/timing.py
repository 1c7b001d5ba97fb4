"""Timing helpers of the study: interleaved timed passes, robust statistics, machine load, first calls."""

from __future__ import annotations

import gc
import os
import time

import numpy as np

from ...collide import Collider
from ...shapes import Prism
from .constants import RADIUS_A, RADIUS_B


def stats(values):
    """Median, min, quartiles and max of ``values`` as floats (keys ``median``, ``min``, ``q1``, ``q3``, ``max``)."""
    v = np.asarray(values, dtype=float)
    q1, med, q3 = np.percentile(v, [25, 50, 75])
    return {"median": float(med), "min": float(v.min()), "q1": float(q1), "q3": float(q3), "max": float(v.max())}


class _NoGC:
    def __enter__(self):
        self.was = gc.isenabled()
        gc.collect()
        gc.disable()

    def __exit__(self, *exc):
        if self.was:
            gc.enable()


def timed_loops(calls, repeats, cpu=None):
    """Warm-up pass, then ``repeats`` interleaved passes; wall seconds per pass per method.

    With a dict ``cpu``, the calling thread's CPU seconds per pass go there too
    (blind to time the thread spent descheduled by other processes).
    """
    for fn in calls.values():
        fn()
    times = {k: [] for k in calls}
    if cpu is not None:
        cpu.update({k: [] for k in calls})
    perf, tcpu = time.perf_counter, time.thread_time
    with _NoGC():
        for _ in range(repeats):
            for k, fn in calls.items():
                c0 = tcpu()
                t0 = perf()
                fn()
                t1 = perf()
                c1 = tcpu()
                times[k].append(t1 - t0)
                if cpu is not None:
                    cpu[k].append(c1 - c0)
    return times


def cpu_snapshot():
    """(wall s, busy CPU-seconds of the whole machine or None, CPU-seconds of this process)."""
    busy = None
    try:
        with open("/proc/stat") as fh:
            f = [int(x) for x in fh.readline().split()[1:]]
        busy = (sum(f[:8]) - f[3] - (f[4] if len(f) > 4 else 0)) / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError, AttributeError):
        pass
    return time.perf_counter(), busy, time.process_time()


def other_load(s0, s1):
    """Average number of CPUs kept busy by OTHER processes between two snapshots (None if unknown)."""
    if s0[1] is None or s1[1] is None or s1[0] - s0[0] < 0.05:
        return None
    return max(0.0, ((s1[1] - s0[1]) - (s1[2] - s0[2])) / (s1[0] - s0[0]))


def compile_times():
    """First call of each prismbatch path on a tiny scene (compile or cache load)."""
    # The kernels module tells whether a kernel was compiled in this process before the first call.
    from ..._kernels import batch as kernels

    a, b = Prism.regular(5, RADIUS_A), Prism.regular(6, RADIUS_B)
    col = Collider(a, b)
    pa = np.zeros((4, 3))
    ra = np.broadcast_to(np.diag([1.0, -1.0, -1.0]), (4, 3, 3)).copy()
    pb_ = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [5.0, 0.0, 0.0], [1.0, 1.0, -0.5]])
    rb = np.broadcast_to(np.eye(3), (4, 3, 3)).copy()
    loaded = {
        name: bool(getattr(getattr(kernels, name, None), "signatures", None))
        for name in ("collide_pair", "collide_serial", "collide_parallel")
    }
    perf = time.perf_counter
    out = {}
    t0 = perf()
    col.collide_pair(pa[0], ra[0], pb_[0], rb[0])
    out["collide_pair_s"] = perf() - t0
    t0 = perf()
    col.collide(pa, ra, pb_, rb, parallel=False)
    out["collide_serial_s"] = perf() - t0
    t0 = perf()
    col.collide(pa, ra, pb_, rb, parallel=True)
    out["collide_parallel_s"] = perf() - t0
    # The same calls again: what a warm call costs, to read the above against.
    t0 = perf()
    col.collide(pa, ra, pb_, rb, parallel=False)
    out["second_serial_call_s"] = perf() - t0
    out["already_compiled_in_process"] = loaded
    out["numba_cache_dir"] = os.environ.get("NUMBA_CACHE_DIR") or "(default: next to the sources)"
    return out
