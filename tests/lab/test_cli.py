"""The prismbatch command: --help, demo output, errors."""

import subprocess
import sys

import pytest

from prismbatch.cli import main
from prismbatch.lab.demo import run_demo


def test_help_lists_demo(capsys):
    with pytest.raises(SystemExit) as e:
        main(["--help"])
    assert e.value.code == 0
    assert "demo" in capsys.readouterr().out


def test_console_script_help():
    out = subprocess.run(
        [sys.executable, "-m", "prismbatch.cli", "demo", "--help"], capture_output=True, text=True, check=True
    ).stdout
    assert "--pairs" in out and "--distribution" in out


def test_demo_prints_throughput_and_cases(capsys):
    assert main(["demo", "--pairs", "3000", "--vertices", "36", "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "throughput" in out and "M pairs/s" in out
    assert "hits:" in out
    assert "case  pairs" in out


def test_demo_counts_are_consistent_and_reproducible():
    r1 = run_demo(n_pairs=5000, n_vertices=36, distribution="free", seed=7, chunk=1500, progress=False)
    r2 = run_demo(n_pairs=5000, n_vertices=36, distribution="free", seed=7, chunk=1500, progress=False)
    assert sum(r1["case_counts"].values()) == 5000
    assert 0 < r1["hits"] < 5000
    assert r1["case_counts"] == r2["case_counts"] and r1["hits"] == r2["hits"]


@pytest.mark.parametrize(
    "argv, flag",
    [
        (["demo", "--pairs", "0"], "--pairs"),
        (["validate", "--pairs", "-5"], "--pairs"),
        (["validate", "--chunk-size", "0"], "--chunk-size"),
        (["validate", "--lp-samples", "-1"], "--lp-samples"),
        (["predict", "--demo", "3", "--workers", "0"], "--workers"),
        (["predict", "--demo", "3", "--max-samples", "x"], "--max-samples"),
    ],
)
def test_a_bad_count_is_named_by_its_flag(capsys, argv, flag):
    """As argparse names any bad option (status 2), not by the function parameter behind it (n_pairs)."""
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 2
    assert f"error: argument {flag}: " in capsys.readouterr().err


def test_help_lists_every_command(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    out = capsys.readouterr().out
    for cmd in ("demo", "experiment", "validate", "study", "workprec", "reproduce", "replay"):
        assert cmd in out


def test_validate_stiff_alone_is_an_error_message(capsys):
    assert main(["validate", "--distributions", "stiff", "--no-progress"]) == 2
    assert "at least one of facing" in capsys.readouterr().err


def test_list_arguments_are_checked(capsys):
    with pytest.raises(SystemExit) as e:
        main(["study", "--vertices", "36,abc"])
    assert e.value.code == 2
    assert "comma-separated integers" in capsys.readouterr().err


def test_a_missing_optional_dependency_is_one_line_with_the_pip_command(monkeypatch, capsys):
    from prismbatch import cli

    def no_matplotlib(args):
        raise ModuleNotFoundError("No module named 'matplotlib'", name="matplotlib")

    def interrupted(args):
        raise KeyboardInterrupt

    def disk_full(args):
        raise OSError(28, "No space left on device", "out/validation.json")

    for fake, status in ((no_matplotlib, 3), (interrupted, 130), (disk_full, 3)):
        monkeypatch.setattr(cli, "_demo", fake)
        assert cli.main(["demo"]) == status
    err = capsys.readouterr().err.splitlines()
    assert err == [
        "prismbatch: matplotlib is not installed: pip install 'prismbatch[plot]'",
        "prismbatch: interrupted",
        "prismbatch: error: [Errno 28] No space left on device: 'out/validation.json'",
    ]


def test_missing_matplotlib_is_reported_before_any_work(monkeypatch, capsys, tmp_path):
    """study/workprec/experiment/reproduce with --out and figures: one line, exit 3, nothing run."""
    import builtins

    from prismbatch.lab import experiment, reproduce, study, workprec

    real_import = builtins.__import__

    def no_matplotlib(name, *args, **kw):
        if name.split(".")[0] == "matplotlib":
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)
        return real_import(name, *args, **kw)

    def must_not_run(*args, **kw):
        raise AssertionError("a run started although its figures could not be drawn")

    for module, name in ((study, "run_study"), (workprec, "run_work_precision"), (experiment, "run_experiment")):
        monkeypatch.setattr(module, name, must_not_run)
    monkeypatch.setattr(reproduce, "run_reproduce", must_not_run)
    monkeypatch.setattr(builtins, "__import__", no_matplotlib)
    for argv in (["study", "--quick"], ["workprec", "--quick"], ["experiment"], ["reproduce", "--quick"]):
        assert main([*argv, "--out", str(tmp_path / argv[0])]) == 3
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 4 and all(line.startswith("prismbatch: figures need matplotlib: pip install") for line in err)
    assert err[0].endswith("(or pass --no-figures)") and not err[3].endswith("--no-figures)")
