"""Sizes that cannot fit are refused with one ValueError naming the memory, before anything is allocated.

The available memory is monkeypatched (``prismbatch.checks.available_memory``)
so that both branches run on any machine without allocating anything large;
tracemalloc confirms that a refused call allocated (almost) nothing.
"""

import os
import tracemalloc

import numpy as np
import pytest

import prismbatch as pb
from prismbatch import checks
from prismbatch.cli import main
from prismbatch.lab.experiment import run as experiment_run
from prismbatch.lab.experiment import run_experiment

GB = 10**9


@pytest.fixture
def memory(monkeypatch):
    """Set the memory the guard sees: ``memory(bytes)`` (None: the OS does not say)."""

    def set_available(nbytes):
        monkeypatch.setattr(checks, "available_memory", lambda: nbytes)

    return set_available


def _peak_bytes(fn):
    """Run ``fn`` (expected to raise ValueError) and return the peak bytes it allocated."""
    tracemalloc.start()
    try:
        with pytest.raises(ValueError) as exc:
            fn()
        return tracemalloc.get_traced_memory()[1], str(exc.value)
    finally:
        tracemalloc.stop()


# ---------------------------------------------------------------------------
# check_memory and the reader
# ---------------------------------------------------------------------------


def test_refuses_more_than_available_and_names_both_sizes(memory):
    memory(int(21.3 * GB))
    with pytest.raises(ValueError) as exc:
        checks.check_memory(48 * GB, "Prism.regular(1000000000)")
    assert str(exc.value) == (
        "Prism.regular(1000000000): needs about 48.0 GB, more than the 21.3 GB of memory available"
    )
    checks.check_memory(20 * GB, "fits")  # below what is available: no error


def test_small_requests_are_never_refused(memory):
    memory(0)
    checks.check_memory(checks._ALWAYS_FITS, "small")
    with pytest.raises(ValueError, match=r"^just over: needs about 67\.1 MB, more than the 0\.0 MB"):
        checks.check_memory(checks._ALWAYS_FITS + 1, "just over")


def test_unknown_available_memory_refuses_nothing(memory):
    memory(None)
    checks.check_memory(1e30, "anything")


def test_absurd_sizes_are_refused_not_overflowed(memory):
    memory(24 * GB)
    with pytest.raises(ValueError, match="needs about inf TB"):
        checks.check_memory(float("inf"), "inf")
    with pytest.raises(ValueError, match="needs about 5000.0 TB"):
        checks.check_memory(5e15, "5 PB")


@pytest.mark.skipif(not os.path.exists("/proc/meminfo"), reason="Linux only")
def test_reader_uses_memavailable():
    with open("/proc/meminfo") as f:
        kib = next(int(line.split()[1]) for line in f if line.startswith("MemAvailable:"))
    got = checks.available_memory()
    # the figure moves while the suite runs: the same order of magnitude, in bytes (not kB)
    assert 0.5 * kib * 1024 < got < 2 * kib * 1024


def test_reader_falls_back_to_sysconf_then_to_none(monkeypatch):
    def no_file(*args, **kwargs):
        raise OSError("no /proc here")

    monkeypatch.setattr(checks, "open", no_file, raising=False)
    pages = {"SC_AVPHYS_PAGES": 1000, "SC_PAGE_SIZE": 4096}
    monkeypatch.setattr(checks.os, "sysconf", lambda name: pages[name])
    assert checks.available_memory() == 4_096_000

    def unknown(name):
        raise ValueError(f"unrecognized configuration name {name}")

    monkeypatch.setattr(checks.os, "sysconf", unknown)
    assert checks.available_memory() is None


# ---------------------------------------------------------------------------
# the shape constructors
# ---------------------------------------------------------------------------


def test_regular_refuses_before_allocating(memory):
    memory(100 * 10**6)
    peak, msg = _peak_bytes(lambda: pb.Prism.regular(2_000_000, 1.0))
    assert msg == "Prism.regular(2000000): needs about 480.0 MB, more than the 100.0 MB of memory available"
    assert peak < 10**6  # 2 million vertices would allocate tens of MB at the first array


def test_regular_above_the_limit_says_the_memory_it_would_need():
    with pytest.raises(ValueError, match=r"got 1000000000 \(it would need about 240\.0 GB of memory\)"):
        pb.Prism.regular(10**9, 1.0)


def test_normal_sizes_pass(memory):
    assert pb.Prism.regular(36, 1.0).n_vertices == 36  # the real reader
    memory(10**6)  # below the smallest size ever checked: a small prism never asks
    assert pb.Prism.regular(3600, 1.0).n_vertices == 3600
    memory(24 * GB)  # a size that is checked, and fits
    assert pb.Prism.regular(400_000, 1.0).n_vertices == 400_000


def test_prism_from_an_array_checks_its_vertex_count(memory):
    xy = np.zeros((400_000, 2))  # never read: refused on its length
    memory(10 * 10**6)
    with pytest.raises(ValueError, match=r"^prism of 400,000 vertices: needs about 96\.0 MB, more than the 10\.0 MB"):
        pb.Prism(xy)


def test_prismset_refuses_the_total_before_building(memory):
    hexagon = pb.Prism.regular(6, 1.0)
    memory(100 * 10**6)
    many = [hexagon] * 200_000  # 1.2 million vertices in all
    peak, msg = _peak_bytes(lambda: pb.PrismSet(many))
    assert msg.startswith("PrismSet of 200,000 polygons, 1,200,000 vertices: needs about 288.0 MB")
    assert peak < 4 * 10**6  # the list of references only, no tables
    assert len(pb.PrismSet([hexagon] * 3)) == 3  # a normal set still builds


# ---------------------------------------------------------------------------
# the experiment's duration, and the command line
# ---------------------------------------------------------------------------


def test_experiment_refuses_a_duration_that_cannot_fit(memory):
    memory(24 * GB)
    peak, msg = _peak_bytes(lambda: run_experiment(duration=1e7, fcl=False))
    assert msg.startswith("experiment of 500,000,001 samples (duration 1e+07 s / dt 0.02 s): needs about 150.0 GB")
    assert msg.endswith("more than the 24.0 GB of memory available")
    assert peak < 10**6  # refused before its shapes, kernels or per-sample arrays


def test_experiment_sample_count_of_normal_durations(memory):
    memory(24 * GB)
    assert experiment_run._check_samples(20.0, 0.02, True) == 1001
    assert experiment_run._check_samples(1e5, 0.02, True) == 5_000_001  # 4.5 GB: checked, and fits


def test_cli_prints_one_line_and_exits_2(memory, capsys):
    memory(24 * GB)
    assert main(["experiment", "--duration", "1e7"]) == 2
    assert main(["demo", "--vertices", "1000000000", "--no-progress"]) == 2
    captured = capsys.readouterr()
    lines = captured.err.splitlines()
    assert len(lines) == 2 and captured.out == ""
    assert lines[0].startswith("prismbatch: error: experiment of 500,000,001 samples")
    assert "needs about 450.0 GB, more than the 24.0 GB" in lines[0]  # with the python-fcl replay
    assert lines[1].startswith("prismbatch: error: Prism.regular: n must be in [3, 10,000,000], got 1000000000")
