"""prismbatch.lab.validate on a Dask LocalCluster gives exactly the in-process results."""

from __future__ import annotations

import os
import sys

import pytest

pytest.importorskip("scipy")
pytest.importorskip("fcl")

from prismbatch.lab import validate as V  # noqa: E402

pytestmark = [pytest.mark.slow, pytest.mark.needs_fcl]

# the distance section: two blocks (256 + 44 pairs)
KW = dict(vertices=(5, 12), shapes=("regular", "random"), seed=21, lp_samples=20, distance_pairs=300, progress=False)
N = 4200  # per distribution: two blocks each (4096 + 104), 16,800 pairs


def test_local_cluster_matches_in_process():
    pytest.importorskip("distributed")
    local = V.validate(N, chunk_size=100_000, **KW)  # one chunk per distribution
    dist = V.validate(N, chunk_size=4096, workers=2, **KW)  # a block a chunk: 8 + 2 tasks, 2 processes
    assert dist.execution["scheduler"] == "dask LocalCluster" and dist.execution["workers"] == 2
    assert dist.execution["numba_threads"] == max(1, (os.cpu_count() or 1) // 2)
    assert local.execution["scheduler"] == "in-process"
    assert dist.outcome() == local.outcome()
    # the comparison is not vacuous: both runs did the work and kept records
    assert sum(c["pairs"] for c in dist.counts.values()) == 4 * N
    assert dist.records and dist.ok
    assert all(dist.times[d]["pb"] > 0 for d in dist.times)


def test_missing_dask_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # import fails
    with pytest.raises(ImportError, match=r"prismbatch\[dask\]"):
        V.validate(10, distributions=("facing",), fcl=False, lp_samples=0, workers=1, progress=False)


def test_run_chunks_needs_a_target():
    from prismbatch.lab.cluster import run_chunks

    with pytest.raises(ValueError, match="scheduler"):
        run_chunks({}, [], lambda s, c: None)
