"""The ``prismbatch`` command line."""

from __future__ import annotations

import argparse
import signal
import sys
import textwrap

from . import __version__


class _LabChoices:
    """argparse choices read from a lab module when first needed (help or parsing), not at import.

    The CLI loads a lab module only for the subcommand that uses it.
    """

    def __init__(self, module, name):
        self.module, self.name = module, name

    def _values(self):
        import importlib

        values = getattr(importlib.import_module(self.module, __package__), self.name)
        return sorted(values) if isinstance(values, dict) else list(values)

    def __iter__(self):
        return iter(self._values())

    def __contains__(self, x):
        return x in self._values()


def _lab_command(name):
    """The runner of subcommand ``name`` in :mod:`prismbatch.lab.commands`, imported when it runs."""

    def run(args):
        import importlib

        return getattr(importlib.import_module(".lab.commands", __package__), f"{name}_command")(args)

    return run


def _demo(args):
    from .collide import CASES
    from .lab.demo import run_demo

    res = run_demo(
        n_pairs=args.pairs,
        n_vertices=args.vertices,
        distribution=args.distribution,
        seed=args.seed,
        contact=args.contact,
        parallel=args.threads != 1,
        progress=not args.no_progress and sys.stderr.isatty(),
    )
    print(
        f"prismbatch {__version__} demo: {res['n_pairs']:,} pose pairs, {res['distribution']} poses, "
        f"{res['n_vertices']}-gon vs {res['n_vertices']}-gon, seed {res['seed']}, "
        f"{res['threads']} thread(s), contact={'yes' if res['contact'] else 'no'}"
    )
    print(f"first call (compile or cache load): {res['compile_s']:.2f} s")
    print(
        f"run time: {res['run_s']:.3f} s   throughput: {res['pairs_per_s'] / 1e6:.2f} M pairs/s "
        f"({1e9 / res['pairs_per_s']:.0f} ns per pair)"
    )
    print(f"hits: {res['hits']:,} ({100.0 * res['hits'] / res['n_pairs']:.1f} %)")
    print("case  pairs       share  meaning")
    for k, v in sorted(res["case_counts"].items()):
        meaning = textwrap.shorten(CASES[k], 70, placeholder=" ...")  # whole words
        print(f"{k:>4}  {v:>10,}  {100.0 * v / res['n_pairs']:5.1f} %  {meaning}")
    return 0


def _at_least(low):
    """An argparse type: an integer >= ``low`` (so that a bad count is named by its flag, exit status 2)."""

    def parse(text):
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
        if v < low:
            raise argparse.ArgumentTypeError(f"must be an integer >= {low}, got {v}")
        return v

    parse.__name__ = f"integer >= {low}"
    return parse


def _int_list(text):
    """Parse '36,180,360' -> (36, 180, 360) for argparse."""
    try:
        vals = tuple(int(v) for v in text.split(",") if v.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated integers, got {text!r}") from None
    if not vals:
        raise argparse.ArgumentTypeError("expected at least one integer")
    return vals


def _name_list(text):
    return tuple(v.strip() for v in text.split(",") if v.strip())


def _add_output_options(p, *, figures=True, what="CSV, JSON, Markdown and figures"):
    """--seed, --out, --no-figures and --no-progress, shared by the result-writing commands."""
    p.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    p.add_argument("--out", default=None, metavar="DIR", help=f"write {what} to DIR")
    if figures:
        p.add_argument("--no-figures", action="store_true", help="with --out: skip the figures")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


def _add_resume_option(p):
    p.add_argument(
        "--resume",
        action="store_true",
        help="continue a run stopped by Ctrl-C, SIGTERM or a crash: the same command and --out load "
        "what it finished from DIR/checkpoint; counts and answers equal an uninterrupted run's (the "
        "timings of the loaded parts are the earlier run's)",
    )


def build_parser():
    """The argument parser (exposed for documentation and tests)."""
    p = argparse.ArgumentParser(
        prog="prismbatch",
        description="Batched collision detection between convex semi-infinite prisms.",
        epilog="Exit status: 0 success; 1 a disagreement or invalid output found (validate, replay); 2 a usage "
        "error; 3 a missing optional dependency or a file that could not be read or written; 130 interrupted.",
    )
    p.add_argument("--version", action="version", version=f"prismbatch {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    _demo_parser(sub)
    _experiment_parser(sub)
    _validate_parser(sub)
    _study_parser(sub)
    _workprec_parser(sub)
    _reproduce_parser(sub)
    _replay_parser(sub)
    _predict_parser(sub)
    return p


def _demo_parser(sub):
    """The ``demo`` subcommand's options."""
    p = sub.add_parser(
        "demo",
        help="collide a batch of random pose pairs and print throughput and case counts",
        description="Collide random pose pairs of the paper's scene (pentagon-sized a, "
        "hexagon-sized b, both regular n-gons) and print throughput and case counts.",
    )
    p.add_argument("--pairs", type=_at_least(1), default=1_000_000, help="number of pose pairs (default: 1,000,000)")
    p.add_argument("--vertices", type=_at_least(3), default=360, help="vertices of each end face (default: 360)")
    p.add_argument(
        "--distribution",
        choices=["facing", "free"],
        default="facing",
        help="pose distribution: the paper's facing scene or uniform random (default: facing)",
    )
    p.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    p.add_argument(
        "--threads",
        type=int,
        default=0,
        help="1 for the serial kernel, k > 1 for k threads, 0 for all of Numba's threads (default: 0)",
    )
    p.add_argument("--contact", action="store_true", help="also compute contact points")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_demo)


def _experiment_parser(sub):
    """The ``experiment`` subcommand's options."""
    p = sub.add_parser(
        "experiment",
        help="simulate the paper's manipulation experiment (Sec. VI-B) with detach control",
        description="Simulate the paper's experiment: b (a 1.5 mm protective cylinder) is driven by a "
        "PD attraction from dC = [2551, -2780, -1970] um to [0, 0, 1000] um past prism a; "
        "collisions trigger the detach controller for one step. Prints the case sequence, "
        "collisions, contact classes, whether the goal is reached, and the detection cost "
        "against python-fcl on the same trajectory. See docs/methods/experiment.md.",
    )
    p.add_argument(
        "--prism",
        choices=_LabChoices(".lab.experiment", "PRISMS"),
        default="square",
        help="object a: square prism, side 3 mm, or triangular prism, side 2.8 mm (default: square)",
    )
    p.add_argument("--vertices", type=_at_least(3), default=3600, help="vertices of b's end face (default: 3600)")
    p.add_argument(
        "--plant",
        choices=_LabChoices(".lab.experiment", "PLANTS"),
        default="velocity",
        help="velocity: the stage follows the commanded velocity; force: m dv/dt = u - c v (default: velocity)",
    )
    p.add_argument("--duration", type=float, default=20.0, help="simulated time in s (default: 20)")
    p.add_argument("--dt", type=float, default=0.02, help="sampling period in s (default: 0.02)")
    p.add_argument(
        "--max-speed", type=float, default=None, help="limit the PD command to this speed in mm/s (default: no limit)"
    )
    p.add_argument("--mass", type=float, default=0.1, help="force plant: mass in kg (default: 0.1)")
    p.add_argument("--damping", type=float, default=1.0, help="force plant: viscous friction in mN s/mm (default: 1)")
    p.add_argument(
        "--detach-tol",
        type=float,
        default=None,
        metavar="MM",
        help="tolerance (mm) for classifying the contact point on a's features "
        "(default: the distance b moved in the last step)",
    )
    p.add_argument(
        "--contact-from",
        choices=("distance", "collide"),
        default="distance",
        help="where detach takes the contact: distance: the penetration's witness point on a and its normal; "
        "collide: collide's contact point, inside both bodies for deep contacts, as the paper (default: distance)",
    )
    p.add_argument(
        "--detach-clearance",
        type=float,
        default=None,
        metavar="UM",
        help="adapt the detach gain at each contact to the predicted approach: the smallest push the plant "
        "model predicts leaves b this far (um) out of contact after the step "
        "(default: the fixed gain 10, as the paper)",
    )
    p.add_argument(
        "--out",
        default=None,
        metavar="DIR",
        help="write CSV, JSON, Markdown and figures (PNG, SVG) to DIR (default: print only)",
    )
    p.add_argument("--no-figures", action="store_true", help="with --out: skip the figures (no matplotlib needed)")
    p.add_argument("--no-fcl", action="store_true", help="skip the python-fcl timing")
    p.set_defaults(func=_lab_command("experiment"))


def _validate_parser(sub):
    """The ``validate`` subcommand's options."""
    p = sub.add_parser(
        "validate",
        help="Monte Carlo validation against python-fcl and an exact LP, per case",
        description="Draw N pose pairs per distribution, run prismbatch, python-fcl on finite "
        "stand-ins and an exact LP (signed margin) on a subsample plus every disagreement, "
        "and report per case: confusion matrices, disagreements inside and outside the "
        "touching band, contact validity, NaN/inf and timings. Every disagreement goes to a "
        "replay file ('prismbatch replay FILE'). Exit status 1 if any disagreement lies "
        "outside the band, a contact is invalid, an output is non-finite or a signed distance is off.",
    )
    p.add_argument(
        "--pairs", type=_at_least(1), default=100_000, metavar="N", help="pairs per distribution (default: 100,000)"
    )
    p.add_argument(
        "--distributions",
        type=_name_list,
        default=("facing", "free", "near-contact", "degenerate"),
        metavar="NAME,...",
        help="facing, free, near-contact, degenerate, and stiff (the stiff and extreme suite, "
        "same as --stiff) (default: the first four)",
    )
    p.add_argument(
        "--shapes",
        type=_name_list,
        default=("regular",),
        metavar="KIND,...",
        help="regular, random (convex polygons), cylinder (n-gon fits); several are cycled per block "
        "(default: regular)",
    )
    p.add_argument(
        "--vertices",
        type=_int_list,
        default=(36, 360),
        metavar="N,N,...",
        help="vertex counts, cycled per block (default: 36,360)",
    )
    p.add_argument(
        "--seed", type=int, default=0, help="random seed; results do not depend on chunking or workers (default: 0)"
    )
    p.add_argument(
        "--chunk-size",
        type=_at_least(1),
        default=50_000,
        metavar="N",
        help="pairs per task: bounds memory (default: 50,000)",
    )
    p.add_argument("--dtype", choices=["float64", "float32"], default="float64", help="precision (default: float64)")
    p.add_argument("--rtol", type=float, default=None, help="relative tolerance (default: 1e-9 f64, 1e-5 f32)")
    p.add_argument("--atol", type=float, default=0.0, help="absolute tolerance (default: 0)")
    p.add_argument("--no-fcl", dest="fcl", action="store_false", help="skip python-fcl")
    p.add_argument(
        "--fcl-fraction",
        type=float,
        default=None,
        metavar="F",
        help="run python-fcl on this random fraction of the pairs (default: all)",
    )
    p.add_argument(
        "--lp-samples",
        type=_at_least(0),
        default=2000,
        metavar="N",
        help="random pairs per distribution checked by the exact LP (default: 2000)",
    )
    p.add_argument("--no-contact-check", action="store_true", help="do not check contact points")
    p.add_argument(
        "--max-band-records",
        type=_at_least(0),
        default=1000,
        metavar="N",
        help="keep at most N 'inside band' records in the replay file (all are counted; default: 1000)",
    )
    p.add_argument(
        "--distance-pairs",
        type=_at_least(0),
        default=None,
        metavar="N",
        help="pairs of the signed-distance section in all, spread evenly over its distance buckets and "
        "checked against the exact reference and coal (0: off; default: the smaller of 1,000 and --pairs)",
    )
    p.add_argument(
        "--distance-vertices",
        type=_int_list,
        default=(3, 36),
        metavar="N,N,...",
        help="vertex counts of the distance section, cycled per block (default: 3,36; the reference costs "
        "about a second a pair of two 360-gons)",
    )
    g = p.add_mutually_exclusive_group()
    g.add_argument("--stiff", action="store_true", help="also run the stiff and extreme suite (a few minutes)")
    g.add_argument("--stiff-quick", action="store_true", help="also run a reduced stiff suite (about 20 s)")
    p.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="send chunks to this Dask scheduler (needs prismbatch[dask])",
    )
    p.add_argument(
        "--workers",
        type=_at_least(1),
        default=None,
        metavar="K",
        help="start a local Dask cluster of K worker processes (when no --scheduler)",
    )
    p.add_argument(
        "--out",
        default=None,
        metavar="DIR",
        help="write validation.md, CSV tables, validation.json and validation_replay.json to DIR; "
        "finished chunks are saved there as they complete (DIR/checkpoint, removed at the end)",
    )
    _add_resume_option(p)
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_lab_command("validate"))


def _study_parser(sub):
    """The ``study`` subcommand's options."""
    p = sub.add_parser(
        "study",
        help="timing study against python-fcl and coal: Table I, Fig. 7, throughput",
        description="Time prismbatch against python-fcl (and coal, when installed) on the same "
        "case-targeted pose pairs: per-case single-query latency at every vertex count "
        "(Table I at 3600 vertices, Fig. 7a-c with fitted growth per 1000 vertices), batch "
        "throughput on one and all threads, compile time apart. Medians of repeats after a "
        "warm-up. Run it on an idle machine.",
    )
    p.add_argument(
        "--quick", action="store_true", help="n = 36, 360, 1800, 3600; 100 poses per case; 3 repeats (about a minute)"
    )
    p.add_argument(
        "--vertices",
        type=_int_list,
        default=None,
        metavar="N,N,...",
        help="vertex counts (default: 36,180,360,1800,3600,7200)",
    )
    p.add_argument("--cases", type=_int_list, default=None, metavar="C,C,...", help="cases (default: 1-11)")
    p.add_argument("--poses", type=_at_least(1), default=None, metavar="N", help="poses per case (default: 300)")
    p.add_argument("--repeats", type=_at_least(1), default=None, metavar="R", help="timed repeats (default: 5)")
    p.add_argument(
        "--batch-pairs",
        type=_at_least(1),
        default=None,
        metavar="N",
        help="pairs per batch-throughput call (default: 100,000)",
    )
    p.add_argument(
        "--peers",
        type=_name_list,
        default=("fcl", "coal"),
        metavar="NAME,...",
        help="peers to time: fcl, coal (default: fcl,coal; coal is skipped with a note if missing)",
    )
    p.add_argument(
        "--table-vertices",
        type=_at_least(3),
        default=None,
        metavar="N",
        help="vertex count of Table I (default: 3600, the paper's, when measured, else the largest measured)",
    )
    p.add_argument(
        "--lp-checks",
        type=_at_least(0),
        default=10,
        metavar="K",
        help="disagreements per cell arbitrated by the exact LP (default: 10)",
    )
    _add_output_options(p)
    _add_resume_option(p)
    p.set_defaults(func=_lab_command("study"))


def _workprec_parser(sub):
    """The ``workprec`` subcommand's options."""
    p = sub.add_parser(
        "workprec",
        help="error against run time: a cylinder as an n-gon prism, vs python-fcl",
        description="Work-precision study: a semi-infinite cylinder approximated by an inscribed n-gon "
        "prism against a hexagonal prism, on near-contact poses with exact labels. For "
        "prismbatch float64/float32 (batch call and single query), python-fcl on the n-gon "
        "and python-fcl's Cylinder: misclassification rate (95 % Wilson intervals, noise "
        "floor) and the geometric error r(1 - cos(pi/n)) against time per query.",
    )
    p.add_argument("--quick", action="store_true", help="n = 8 ... 10000 (6 values), 10,000 poses, 2 repeats")
    p.add_argument(
        "--vertices",
        type=_int_list,
        default=None,
        metavar="N,N,...",
        help="vertex counts of the n-gon (default: 8 ... 100000, 11 values)",
    )
    p.add_argument("--poses", type=_at_least(1), default=None, metavar="N", help="near-contact poses (default: 20,000)")
    p.add_argument("--radius", type=float, default=1.0, help="cylinder radius (default: 1)")
    p.add_argument("--repeats", type=_at_least(1), default=None, metavar="R", help="timed passes (default: 3)")
    p.add_argument("--no-fcl", dest="fcl", action="store_false", help="skip python-fcl (its rows stay, as NaN)")
    _add_output_options(p)
    _add_resume_option(p)
    p.set_defaults(func=_lab_command("workprec"))


def _reproduce_parser(sub):
    """The ``reproduce`` subcommand's options."""
    p = sub.add_parser(
        "reproduce",
        help="run validation, timing study, work-precision and experiment; one report",
        description="Run a short Monte Carlo validation (with the stiff suite), the timing study "
        "against python-fcl and coal, the work-precision study and the paper's experiment, "
        "and write everything into one folder: figures (PNG, SVG), CSV tables, JSON "
        "metadata (versions, CPU, threads, seeds) and report.md. Needs "
        "'prismbatch[reproduce]'. notebooks/reproduce.ipynb redraws the figures from the CSVs.",
    )
    p.add_argument("--quick", action="store_true", help="smaller runs of every part (a few minutes on 2 cores)")
    p.add_argument("--out", default="reproduce-output", metavar="DIR", help="output folder (default: reproduce-output)")
    p.add_argument(
        "--parts",
        type=_name_list,
        default=None,
        metavar="PART,...",
        help="only these parts: validation, study, workprec, experiment (default: all)",
    )
    p.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.set_defaults(func=_lab_command("reproduce"))


def _replay_parser(sub):
    """The ``replay`` subcommand's options."""
    p = sub.add_parser(
        "replay",
        help="re-run saved pose pairs and print how each is decided, step by step",
        description="Re-run the pose pairs of a replay file (e.g. validation_replay.json written by "
        "'prismbatch validate') and print, for each, b's pose in a's frame, the case "
        "classification, every test on the way and where the decision was made.",
    )
    p.add_argument("file", help="replay file (JSON)")
    p.add_argument(
        "--record",
        type=int,
        action="append",
        default=None,
        metavar="I",
        help="only record I (0-based; repeat for several)",
    )
    p.set_defaults(func=_lab_command("replay"))


def _predict_parser(sub):
    p = sub.add_parser(
        "predict",
        help="time of impact and probability of collision of queries from a file (or a random demo set)",
        description="Collision prediction: for each query, the first time within the horizon at which b, moving "
        "with its velocity and angular velocity, touches a (prismbatch.motion.time_of_impact), and the "
        "probability that the two collide under Gaussian pose noise with its confidence interval "
        "(prismbatch.probability.collision_probability). Queries come from a .npz file with arrays xy_a, xy_b, "
        "pos_a, rot_a, pos_b, rot_b and velocity [angular_velocity, horizon] and/or cov_b [cov_a] (see "
        "prismbatch.lab.queries.KEYS), or --demo N random ones. Writes predict.csv (a row per query) and "
        "predict.json (settings, counts, timings) with --out.",
    )
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("queries", nargs="?", metavar="FILE.npz", help="the query file")
    src.add_argument("--demo", type=int, metavar="N", help="N random queries from --seed (b moving towards a)")
    p.add_argument("--horizon", type=float, default=1.0, help="look-ahead of queries without their own (default: 1)")
    p.add_argument("--rel-error", type=float, default=0.1, help="probability: target relative error (default 0.1)")
    p.add_argument("--confidence", type=float, default=0.95, help="probability: interval level (default 0.95)")
    p.add_argument(
        "--max-samples", type=_at_least(1), default=1_000_000, help="probability: budget per query (default 1e6)"
    )
    p.add_argument(
        "--quat-order", choices=("xyzw", "wxyz"), default=None, help="order of quaternion rotations in the file"
    )
    p.add_argument("--chunk-size", type=_at_least(1), default=1024, help="queries per task (default: 1024)")
    p.add_argument(
        "--workers", type=_at_least(1), default=None, help="run on a local Dask cluster of this many processes"
    )
    p.add_argument("--scheduler", default=None, metavar="ADDRESS", help="run on an existing Dask scheduler")
    _add_output_options(p, figures=False, what="predict.csv and predict.json")
    p.set_defaults(func=_lab_command("predict"))


def main(argv=None):
    """Entry point of the ``prismbatch`` console command."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    previous = _stop_on_sigterm()
    try:
        if getattr(args, "threads", 0) > 1:
            import numba

            numba.set_num_threads(args.threads)  # raises ValueError above the available threads
        if getattr(args, "out", None) is not None:
            from .lab.report import check_writable

            check_writable(args.out)  # before any work, not after an hour of it
        return args.func(args)
    except (ValueError, TypeError) as exc:
        print(f"prismbatch: error: {exc}", file=sys.stderr)
        return 2
    except ImportError as exc:  # an optional dependency: one line, with the pip command
        print(f"prismbatch: {_missing_dependency(exc)}", file=sys.stderr)
        return 3
    except OSError as exc:  # a file could not be read or written (a full disk, no permission)
        print(f"prismbatch: error: {exc}", file=sys.stderr)
        return 3
    except KeyboardInterrupt as exc:
        print(f"prismbatch: {_interrupted(exc)}", file=sys.stderr)
        return 130
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


def _stop_on_sigterm():
    """SIGTERM (a batch system's stop, ``kill``) stops a run as Ctrl-C does; returns the old handler."""

    def stop(signum, frame):
        raise KeyboardInterrupt

    try:
        return signal.signal(signal.SIGTERM, stop)
    except ValueError:  # not the main thread (main() called from a thread): leave SIGTERM alone
        return None


def _interrupted(exc):
    """The one-line message of an interrupt: what was finished and kept, and how to continue."""
    from .lab.checkpoint import Interrupted

    if not isinstance(exc, Interrupted):
        return "interrupted"
    if exc.files:
        where = exc.files.get("markdown") or next(iter(exc.files.values()))
        return f"{exc}; partial report {where}; the same command with --resume continues"
    if exc.checkpoint is not None:
        return f"{exc}; finished {exc.unit}s kept in {exc.checkpoint.dir}; the same command with --resume continues"
    return f"{exc}; nothing kept (no --out)"


#: The extra that installs a module the lab imports when a subcommand needs it.
_EXTRAS = {"matplotlib": "plot", "fcl": "fcl", "coal": "coal", "scipy": "exact", "highspy": "exact", "tqdm": "progress"}


def _missing_dependency(exc):
    """The message of an ImportError, with the pip command when it is a bare "No module named ..."."""
    root = (exc.name or "").split(".")[0]
    if root in _EXTRAS and "pip install" not in str(exc):
        return f"{root} is not installed: pip install 'prismbatch[{_EXTRAS[root]}]'"
    if root in ("dask", "distributed") and "pip install" not in str(exc):
        return "dask is not installed: pip install 'prismbatch[dask]'"
    return str(exc)


if __name__ == "__main__":
    sys.exit(main())
