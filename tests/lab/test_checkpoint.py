"""Long runs lose nothing: atomic files, the output folder checked first, checkpoints, resume.

An interrupted validation run resumed with the same settings must give exactly the counts and
records of an uninterrupted run; a stop (SIGTERM) of the real command is one line and exit 130.
"""

from __future__ import annotations

import glob
import json
import os
import signal
import subprocess
import sys
import time

import pytest

from prismbatch.lab import validate as V
from prismbatch.lab.checkpoint import Checkpoint, Interrupted
from prismbatch.lab.report import atomic_open, check_writable, write_json

# A run with several chunks of one block each, no FCL, no LP: seconds, no extra needed.
SMALL = dict(
    distributions=("facing", "near-contact"),
    vertices=(12, 36),
    seed=3,
    chunk_size=V.BLOCK_SIZE,
    fcl=False,
    lp_samples=0,
    progress=False,
)
N_PAIRS = 3 * V.BLOCK_SIZE + 100  # four chunks per distribution, the last one short


def test_atomic_open_leaves_the_old_file_when_writing_fails(tmp_path):
    path = tmp_path / "r.json"
    write_json(path, {"old": 1})
    with pytest.raises(RuntimeError, match="disk"):
        with atomic_open(path, "w") as f:
            f.write('{"new": ')
            raise RuntimeError("disk full half-way")
    assert json.loads(path.read_text()) == {"old": 1}
    assert os.listdir(tmp_path) == ["r.json"]  # no temporary file left behind


def test_an_unwritable_output_folder_is_refused_before_any_work(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(OSError, match=f"cannot write to --out {blocker}/sub"):
        check_writable(blocker / "sub")
    assert check_writable(tmp_path / "new" / "dir") == str(tmp_path / "new" / "dir")
    assert os.listdir(tmp_path / "new" / "dir") == []  # the probe file is removed


def test_a_checkpoint_resumes_only_the_same_settings(tmp_path):
    ck = Checkpoint(tmp_path, "validate", {"seed": 1, "n": 10})
    ck.save("a", [1, 2])
    assert Checkpoint(tmp_path, "validate", {"seed": 1, "n": 10}, resume=True).load("a") == [1, 2]
    with pytest.raises(ValueError, match=r"other settings \(seed\)"):
        Checkpoint(tmp_path, "validate", {"seed": 2, "n": 10}, resume=True)
    fresh = Checkpoint(tmp_path, "validate", {"seed": 2, "n": 10})  # no --resume: start again
    assert fresh.load("a") is None
    fresh.remove()
    assert not (tmp_path / "checkpoint").exists()


def test_a_damaged_checkpoint_unit_is_computed_again(tmp_path):
    """A unit file cut short or overwritten after it was written is not a finished unit: load gives
    None (the run computes it again) with a warning naming the file, not an unpickling traceback."""
    ck = Checkpoint(tmp_path, "validate", {"seed": 1})
    ck.save("a", list(range(1000)))
    ck.save("b", [3])
    path = glob.glob(str(tmp_path / "checkpoint" / "validate" / "a.pickle"))[0]
    data = open(path, "rb").read()
    for damaged in (data[: len(data) // 2], b"garbage", b""):
        with open(path, "wb") as f:
            f.write(damaged)
        resumed = Checkpoint(tmp_path, "validate", {"seed": 1}, resume=True)
        with pytest.warns(RuntimeWarning, match="a.pickle cannot be read"):
            assert resumed.load("a") is None
        assert resumed.load("b") == [3]


def test_an_interrupted_validation_resumes_to_the_uninterrupted_counts(tmp_path, monkeypatch):
    from prismbatch.lab.validate import driver

    whole = V.validate(N_PAIRS, **SMALL)
    real = driver.run_chunk
    calls = []

    def stop_on_the_fifth(cfg, *spec):
        calls.append(spec)
        if len(calls) == 5:
            raise KeyboardInterrupt
        return real(cfg, *spec)

    monkeypatch.setattr(driver, "run_chunk", stop_on_the_fifth)
    with pytest.raises(Interrupted) as e:
        V.validate(N_PAIRS, **SMALL, checkpoint_dir=tmp_path)
    part = e.value.result
    # the distance section's 1,000 pairs (four blocks) run after the collision pairs: none done yet
    done = {"pairs_done": 3 * V.BLOCK_SIZE + 100, "pairs_total": 2 * N_PAIRS}
    assert part.partial == {**done, "distance_pairs_done": 0, "distance_pairs_total": 1000}
    assert len(glob.glob(str(tmp_path / "checkpoint" / "validate" / "*.pickle"))) == 4
    paths = V.write_validation(part, tmp_path)  # the partial report says so and keeps the checkpoint
    assert "PARTIAL (12,388 of 24,776 pairs and 0 of 1,000 signed-distance pairs" in open(paths["markdown"]).read()
    assert json.load(open(paths["json"]))["partial"]["pairs_done"] == 12388
    assert (tmp_path / "checkpoint" / "validate").is_dir()

    monkeypatch.setattr(driver, "run_chunk", real)
    calls.clear()
    resumed = V.validate(N_PAIRS, **SMALL, checkpoint_dir=tmp_path, resume=True)
    assert resumed.execution["chunks_resumed"] == 4
    assert resumed.partial is None
    assert resumed.outcome() == whole.outcome()  # every count and record, not only the totals
    V.write_validation(resumed, tmp_path)
    assert not (tmp_path / "checkpoint").exists()  # removed once the full report is written


def test_an_interrupted_distance_section_counts_its_pairs(monkeypatch):
    from prismbatch.lab.validate import driver
    from prismbatch.lab.validate.distance import DISTANCE_BLOCK

    real = driver.run_chunk
    calls = []

    def stop_in_the_second_distance_block(cfg, *spec):
        calls.append(spec)
        if len(calls) == 8 + 2:  # after the 8 collision chunks and one distance block
            raise KeyboardInterrupt
        return real(cfg, *spec)

    monkeypatch.setattr(driver, "run_chunk", stop_in_the_second_distance_block)
    with pytest.raises(Interrupted) as e:
        V.validate(N_PAIRS, **SMALL)
    assert e.value.result.partial == {
        "pairs_done": 2 * N_PAIRS,
        "pairs_total": 2 * N_PAIRS,
        "distance_pairs_done": DISTANCE_BLOCK,
        "distance_pairs_total": 1000,
    }
    assert (e.value.done, e.value.total) == (2 * N_PAIRS + DISTANCE_BLOCK, 2 * N_PAIRS + 1000)


def test_sigterm_stops_the_command_with_one_line_and_status_130(tmp_path):
    """The real command in its own process: SIGTERM once chunks are being saved."""
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "prismbatch", "validate", "--pairs", "400000", "--no-fcl", "--lp-samples", "0"]
    cmd += ["--chunk-size", "4096", "--distributions", "facing", "--no-progress", "--out", str(out)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while not glob.glob(str(out / "checkpoint" / "validate" / "*.pickle")) and time.monotonic() < deadline:
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.05)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("prismbatch: interrupted after "), err
    assert "the same command with --resume continues" in lines[0]
    assert "PARTIAL" in (out / "validation.md").read_text()


def test_an_interrupted_study_resumes_from_its_finished_vertex_counts(tmp_path, monkeypatch):
    from prismbatch.lab.study import run as study_run

    small = dict(vertices=(12, 24), cases=(1, 6), poses_per_case=8, repeats=1, batch_pairs=64)
    small.update(peers=(), lp_checks=0, progress=False)
    whole = study_run.run_study(**small)
    real = study_run._measure_vertices

    def stop_at_24(n, *args):
        if n == 24:
            raise KeyboardInterrupt
        return real(n, *args)

    monkeypatch.setattr(study_run, "_measure_vertices", stop_at_24)
    with pytest.raises(Interrupted) as e:
        study_run.run_study(**small, checkpoint_dir=tmp_path)
    assert (e.value.done, e.value.total) == (1, 2)
    monkeypatch.setattr(study_run, "_measure_vertices", real)
    resumed = study_run.run_study(**small, checkpoint_dir=tmp_path, resume=True)
    assert resumed.settings["resumed_vertices"] == [12]
    assert resumed.agreement == whole.agreement  # the answers, not the timings
    assert [(r["vertices"], r["case"], r["method"]) for r in resumed.latency] == [
        (r["vertices"], r["case"], r["method"]) for r in whole.latency
    ]
    with pytest.raises(ValueError, match="other settings"):
        study_run.run_study(**{**small, "repeats": 2}, checkpoint_dir=tmp_path, resume=True)
