"""The lab's shared number formatter and timing helpers."""

import math
import time

import numpy as np
import pytest

from prismbatch.lab.report import fmt, pct
from prismbatch.lab.timing import best_of, gc_paused, other_load, stats, timed_loops


@pytest.mark.parametrize(
    ("x", "kw", "text"),
    [
        (None, {}, "-"),
        (math.nan, {}, "-"),
        (math.inf, {"none": "nan"}, "nan"),
        (np.float32("nan"), {}, "-"),
        (5030.4, {}, "5030"),  # no exponent between 1000 and 1e7
        (1.5e8, {}, "1.5e+08"),
        (0.012345, {}, "0.0123"),
        (12, {}, "12"),
        (np.int64(123456789), {}, "123456789"),  # integers print whole
        (7, {"spec": "5d"}, "    7"),
        (True, {}, "True"),
        ("case 1", {}, "case 1"),
        (2.5, {"spec": ".2f", "unit": " s"}, "2.50 s"),
        (None, {"spec": ".2f", "unit": " s"}, "-"),
    ],
)
def test_fmt(x, kw, text):
    assert fmt(x, **kw) == text


def test_pct():
    assert pct(0.028) == "2.8 %" and pct(None) == "-"


def test_timed_loops_interleaves_and_counts_every_pass():
    calls = []
    times = timed_loops({"a": lambda: calls.append("a"), "b": lambda: calls.append("b")}, 3, warmup=1)
    assert calls == ["a", "b"] * 4
    assert {k: len(v) for k, v in times.items()} == {"a": 3, "b": 3}


def test_best_of_returns_the_minimum_and_the_last_result():
    n = iter(range(5))
    best, out = best_of(3, lambda: (time.sleep(0.001), next(n))[1])
    assert out == 2 and 0.001 <= best < 1.0


def test_stats_and_gc_paused():
    s = stats([4.0, 1.0, 3.0, 2.0, 5.0])
    assert s == {"median": 3.0, "min": 1.0, "q1": 2.0, "q3": 4.0, "max": 5.0}
    import gc

    with gc_paused():
        assert not gc.isenabled()
    assert gc.isenabled()
    assert other_load((0.0, None, 0.0), (1.0, 5.0, 0.5)) is None
    assert other_load((0.0, 10.0, 1.0), (1.0, 11.5, 1.5)) == pytest.approx(1.0)


def test_thread_use_is_cpu_time_over_wall_time_of_repeated_calls():
    import time

    from prismbatch.lab.timing import thread_use

    def busy():  # one thread, all CPU: about 1
        t = time.perf_counter()
        while time.perf_counter() - t < 0.01:
            pass

    assert 0.5 < thread_use(busy, min_seconds=0.2) < 1.3
    # sleeping calls use (almost) no CPU
    assert thread_use(lambda: time.sleep(0.01), min_seconds=0.2) < 0.3
