"""Timing helpers shared by the study, the work-precision run, the experiment and ``benchmarks/``.

Timed passes run with the garbage collector paused and the methods interleaved
(so that a change in machine load falls on all of them); statistics are robust
(median and quartiles); the CPU time other processes took during a measurement
is read from ``/proc/stat`` so a report can say how quiet the machine was; a
first call (compilation or cache load) is timed apart from the warm calls.
"""

from __future__ import annotations

import gc
import math
import os
import time
from contextlib import contextmanager

import numpy as np

__all__ = [
    "stats",
    "gc_paused",
    "timed_loops",
    "best_of",
    "seconds_of",
    "thread_use",
    "cpu_snapshot",
    "other_load",
    "threads",
    "IdleWaiter",
]


def stats(values):
    """Median, min, quartiles and max of ``values`` as floats (keys ``median``, ``min``, ``q1``, ``q3``, ``max``)."""
    v = np.asarray(values, dtype=float)
    q1, med, q3 = np.percentile(v, [25, 50, 75])
    return {"median": float(med), "min": float(v.min()), "q1": float(q1), "q3": float(q3), "max": float(v.max())}


@contextmanager
def gc_paused():
    """Collect the young generations, then keep the garbage collector off for the block (restored after).

    Not a full collection: its cost grows with every object the process holds
    (0.23 s with 3 million live objects), and the timing loops enter this block
    hundreds of times per study.
    """
    was = gc.isenabled()
    gc.collect(1)
    gc.disable()
    try:
        yield
    finally:
        if was:
            gc.enable()


def timed_loops(calls, repeats, cpu=None, cpu_clock=time.thread_time, warmup=1):
    """``warmup`` passes, then ``repeats`` interleaved passes; wall seconds per pass per method.

    ``calls`` maps a name to a function of no arguments. With a dict ``cpu``,
    the CPU seconds of ``cpu_clock`` per pass go there too: ``time.thread_time``
    (the default) is blind to time the thread spent descheduled by other
    processes; ``time.process_time`` counts every thread of a parallel call.
    """
    for _ in range(warmup):
        for fn in calls.values():
            fn()
    times = {k: [] for k in calls}
    if cpu is not None:
        cpu.update({k: [] for k in calls})
    perf = time.perf_counter
    with gc_paused():
        for _ in range(repeats):
            for k, fn in calls.items():
                c0 = cpu_clock()
                t0 = perf()
                fn()
                t1 = perf()
                c1 = cpu_clock()
                times[k].append(t1 - t0)
                if cpu is not None:
                    cpu[k].append(c1 - c0)
    return times


def best_of(repeats, call):
    """Fastest wall time (s) of ``repeats`` calls of ``call()``, and the last call's result."""
    perf = time.perf_counter
    best = math.inf
    out = None
    for _ in range(repeats):
        t0 = perf()
        out = call()
        best = min(best, perf() - t0)
    return best, out


def seconds_of(call):
    """Wall seconds of one call of ``call()`` (a first call: compilation or cache load included)."""
    t0 = time.perf_counter()
    call()
    return time.perf_counter() - t0


def cpu_snapshot():
    """(wall s, busy CPU-seconds of the whole machine or None, CPU-seconds of this process)."""
    busy = None
    try:
        with open("/proc/stat") as fh:
            f = [int(x) for x in fh.readline().split()[1:]]
        idle = f[3] + (f[4] if len(f) > 4 else 0)  # idle + iowait
        busy = (sum(f[:8]) - idle) / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError, AttributeError):
        pass
    return time.perf_counter(), busy, time.process_time()


def other_load(s0, s1):
    """Average number of CPUs kept busy by OTHER processes between two snapshots (None if unknown)."""
    if s0[1] is None or s1[1] is None or s1[0] - s0[0] < 0.05:
        return None
    return max(0.0, ((s1[1] - s0[1]) - (s1[2] - s0[2])) / (s1[0] - s0[0]))


@contextmanager
def threads(k):
    """``numba.set_num_threads(k)`` for the block (at most Numba's thread pool), restored after; yields the count."""
    import numba

    old = numba.get_num_threads()
    numba.set_num_threads(max(1, min(int(k), numba.config.NUMBA_NUM_THREADS)))
    try:
        yield numba.get_num_threads()
    finally:
        numba.set_num_threads(old)


class IdleWaiter:
    """Waits for other processes to leave the CPUs idle, within a total budget.

    On a shared machine this keeps e.g. a concurrent test run from skewing the
    numbers (an OpenMP region whose threads share a core with another process
    can be several times slower than one thread).  ``budget`` seconds are
    shared by the whole run; once spent, measurements proceed regardless.
    """

    def __init__(self, budget, log=None, threshold=0.25, window=2.0):
        self.left = float(budget)
        self.log = log
        self.threshold = threshold
        self.window = window

    @property
    def active(self):
        return self.left > 0.0

    def wait(self):
        """Block until idle or the budget is spent; returns seconds waited."""
        t0 = time.perf_counter()
        warned = False
        while self.left > 0.0:
            s0 = cpu_snapshot()
            time.sleep(self.window)
            other = other_load(s0, cpu_snapshot())
            self.left -= self.window
            if other is None or other < self.threshold:
                break
            if self.log and not warned:
                self.log(
                    f"  waiting for other processes to go idle ({other:.2f} CPUs busy; "
                    f"{max(self.left, 0):.0f} s of waiting budget left)..."
                )
                warned = True
        return time.perf_counter() - t0


def thread_use(fn, min_seconds=0.4):
    """Process CPU time / wall time of back-to-back calls of fn for >= min_seconds.

    Per-repeat CPU times of millisecond calls are at the mercy of the kernel's
    CPU-time accounting granularity, so thread use is measured on its own.
    """
    fn()
    c0, t0 = time.process_time(), time.perf_counter()
    while True:
        fn()
        t1 = time.perf_counter()
        if t1 - t0 >= min_seconds:
            break
    return (time.process_time() - c0) / (t1 - t0)
