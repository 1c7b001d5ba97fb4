"""What each lab subcommand of the ``prismbatch`` command line does (its options are in
:mod:`prismbatch.cli`, which imports this module only when such a command runs).

Every runner takes the parsed arguments and returns the exit status.
"""

from __future__ import annotations

import functools
import sys

from .checkpoint import discard
from .report import MPL_MISSING

__all__ = [
    "experiment_command",
    "study_command",
    "validate_command",
    "workprec_command",
    "reproduce_command",
    "replay_command",
    "predict_command",
]


def _check_figures(args, hint=" (or pass --no-figures)"):
    """Fail before any work, not after it, when figures are asked for and matplotlib is missing."""
    if args.out is not None and not getattr(args, "no_figures", False):
        try:
            import matplotlib  # noqa: F401
        except ImportError:
            raise ImportError(MPL_MISSING + hint) from None


def experiment_command(args):
    from .experiment import format_summary, run_experiment, write_experiment

    _check_figures(args)
    res = run_experiment(
        args.prism,
        vertices=args.vertices,
        plant=args.plant,
        duration=args.duration,
        dt=args.dt,
        max_speed=args.max_speed,
        mass=args.mass,
        damping=args.damping,
        detach_tol=args.detach_tol,
        contact_from=args.contact_from,
        detach_clearance_um=args.detach_clearance,
        fcl=not args.no_fcl,
    )
    for line in format_summary(res):
        print(line)
    if args.out is None:
        print("(no files written: pass --out DIR for the trajectory CSV, JSON metadata, Markdown summary and figures)")
        return 0
    paths = write_experiment(res, args.out, figures=not args.no_figures)
    print(f"wrote {paths['csv']}, {paths['json']}, {paths['markdown']}")
    for f in paths["figures"]:
        print(f"wrote {f}")
    return 0


def _print_paths(paths):
    for key, v in paths.items():
        for f in v if isinstance(v, (list, tuple)) else [v]:
            print(f"wrote {f}")


def study_command(args):
    from .study import format_study, run_study, write_study

    _check_resume(args)
    _check_figures(args)
    res = run_study(
        vertices=args.vertices,
        cases=args.cases or tuple(range(1, 12)),
        poses_per_case=args.poses,
        repeats=args.repeats,
        batch_pairs=args.batch_pairs,
        peers=args.peers,
        seed=args.seed,
        quick=args.quick,
        progress=_show_progress(args),
        lp_checks=args.lp_checks,
        table_vertices=args.table_vertices,
        checkpoint_dir=args.out,
        resume=args.resume,
    )
    for line in format_study(res):
        print(line)
    if args.out is not None:
        _print_paths(write_study(res, args.out, figures=not args.no_figures))
        discard(args.out, "study")  # every file is written: the finished vertex counts are not needed
    return 0


def validate_command(args):
    from .validate import format_validation, validate, write_validation

    if args.fcl_fraction is not None and not args.fcl:
        raise ValueError("--fcl-fraction and --no-fcl contradict each other")
    stiff = "quick" if args.stiff_quick else bool(args.stiff)
    dists = tuple(d for d in args.distributions if d != "stiff")
    if len(dists) < len(args.distributions):  # "stiff" names the stiff suite, which has its own generators
        stiff = stiff or True
    if not dists:
        raise ValueError(
            "--distributions needs at least one of facing, free, near-contact, degenerate "
            "(stiff adds the stiff suite to them)"
        )
    _check_resume(args)
    shapes = args.shapes[0] if len(args.shapes) == 1 else args.shapes
    run = functools.partial(
        validate,
        args.pairs,
        distributions=dists,
        shapes=shapes,
        vertices=args.vertices,
        seed=args.seed,
        chunk_size=args.chunk_size,
        dtype=args.dtype,
        rtol=args.rtol,
        atol=args.atol,
        fcl=args.fcl_fraction if args.fcl_fraction is not None else args.fcl,
        lp_samples=args.lp_samples,
        contact_check=not args.no_contact_check,
        max_band_records=args.max_band_records,
        distance_pairs=args.distance_pairs,
        distance_vertices=args.distance_vertices,
        stiff=stiff,
        scheduler=args.scheduler,
        workers=args.workers,
        progress=_show_progress(args),
        checkpoint_dir=args.out,
        resume=args.resume,
    )
    res = _run_or_write_partial(run, lambda partial: write_validation(partial, args.out) if args.out else {})
    for line in format_validation(res):
        print(line)
    if args.out is not None:
        _print_paths(write_validation(res, args.out))
    else:
        print("(no files written: pass --out DIR for the report, CSV tables, JSON metadata and the replay file)")
    return 0 if res.ok else 1


def _run_or_write_partial(run, write):
    """``run()``; when it is interrupted, ``write`` its partial result before passing the interrupt on."""
    from .checkpoint import Interrupted

    try:
        return run()
    except Interrupted as exc:
        exc.files = write(exc.result)
        raise


def workprec_command(args):
    from .workprec import format_work_precision, run_work_precision, write_work_precision

    _check_resume(args)
    _check_figures(args)
    res = run_work_precision(
        vertices=args.vertices,
        n_poses=args.poses,
        radius=args.radius,
        repeats=args.repeats,
        seed=args.seed,
        quick=args.quick,
        progress=_show_progress(args),
        fcl=args.fcl,
        checkpoint_dir=args.out,
        resume=args.resume,
    )
    for line in format_work_precision(res):
        print(line)
    if args.out is not None:
        _print_paths(write_work_precision(res, args.out, figures=not args.no_figures))
        discard(args.out, "workprec")
    return 0


def reproduce_command(args):
    from .reproduce import run_reproduce

    _check_figures(args, hint="")
    res = run_reproduce(
        args.out, quick=args.quick, seed=args.seed, parts=args.parts or None, progress_bar=_show_progress(args)
    )
    print(f"wrote {len(res['files'])} files to {args.out}; report: {res['report']}")
    return 0


def _check_resume(args):
    if args.resume and args.out is None:
        raise ValueError("--resume needs the --out DIR of the run to continue")


def _show_progress(args):
    return not args.no_progress and sys.stderr.isatty()


def replay_command(args):
    from .replay import replay

    try:
        replay(args.file, indices=args.record)
    except OSError as exc:
        print(f"prismbatch: error: cannot read {args.file}: {exc.strerror or exc}", file=sys.stderr)
        return 3  # (the documented status of a file that cannot be read)
    return 0


def predict_command(args):
    import numpy as np

    from .queries import MEANINGS, answer, csv_table, demo_queries, read_queries
    from .report import run_metadata, write_csv, write_json

    if args.demo is not None and args.demo < 1:
        raise ValueError(f"--demo must be at least 1, got {args.demo}")
    q = demo_queries(args.demo, args.seed) if args.demo is not None else read_queries(args.queries)
    res = answer(
        q,
        horizon=args.horizon,
        seed=args.seed,
        quat_order=args.quat_order,
        workers=args.workers,
        scheduler=args.scheduler,
        chunk_size=args.chunk_size,
        rel_error=args.rel_error,
        confidence=args.confidence,
        max_samples=args.max_samples,
    )
    toi, pr = res["toi"], res["probability"]
    source = f"{args.demo} random queries (seed {args.seed})" if args.demo is not None else args.queries
    summary = {"queries": source}
    print(f"prismbatch predict: {source}")
    if toi is not None:
        summary["time_of_impact"] = {
            "queries": len(toi),
            "contact": int(toi.hit.sum()),
            "clear": int(np.count_nonzero(toi.status == 0)),
            "undecided": int(np.count_nonzero(toi.status == -1)),
            "median_iterations": float(np.median(toi.iterations)),
            "seconds": res["seconds"]["time_of_impact"],
        }
        s = summary["time_of_impact"]
        print(
            f"time of impact: {s['contact']} contact(s), {s['clear']} clear within the horizon, "
            f"{s['undecided']} undecided; median {s['median_iterations']:g} steps; {s['seconds']:.2f} s"
        )
    if pr is not None:
        summary["probability"] = {
            "queries": len(pr.p),
            "converged": int(pr.converged.sum()),
            "samples_total": int(pr.samples.sum()),
            "median_p": float(np.median(pr.p)),
            "max_p": float(pr.p.max()),
            "seed": int(pr.seed),
            "execution": res["execution"],
            "seconds": res["seconds"]["probability"],
        }
        s = summary["probability"]
        print(
            f"probability of collision: {s['converged']} of {s['queries']} met --rel-error "
            f"{args.rel_error:g} at {args.confidence:g} confidence; {s['samples_total']:,} samples; "
            f"median p {s['median_p']:.3g}, max {s['max_p']:.3g}; {s['seconds']:.2f} s "
            f"({res['execution']['scheduler']})"
        )
    if args.out is None:
        print("(no files written: pass --out DIR for predict.csv and predict.json)")
        return 0
    from pathlib import Path

    out = Path(args.out)
    csv_path = write_csv(out / "predict.csv", *csv_table(res))
    settings = {k: getattr(args, k) for k in ("horizon", "rel_error", "confidence", "max_samples", "seed")}
    json_path = write_json(
        out / "predict.json",
        run_metadata(
            description="prismbatch collision prediction", settings=settings, summary=summary, columns=MEANINGS
        ),  # fmt: skip
    )
    print(f"wrote {csv_path}, {json_path}")
    return 0
