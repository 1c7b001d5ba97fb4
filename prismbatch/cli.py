"""The ``prismbatch`` command line."""

from __future__ import annotations

import argparse
import sys

from . import __version__
from .experiment import PLANTS, PRISMS


def _demo(args):
    from .collide import CASES
    from .demo import run_demo

    res = run_demo(n_pairs=args.pairs, n_vertices=args.vertices, distribution=args.distribution,
                   seed=args.seed, contact=args.contact, parallel=args.threads != 1,
                   progress=not args.no_progress and sys.stderr.isatty())
    print(f"prismbatch {__version__} demo: {res['n_pairs']:,} pose pairs, {res['distribution']} poses, "
          f"{res['n_vertices']}-gon vs {res['n_vertices']}-gon, seed {res['seed']}, "
          f"{res['threads']} thread(s), contact={'yes' if res['contact'] else 'no'}")
    print(f"first call (compile or cache load): {res['compile_s']:.2f} s")
    print(f"run time: {res['run_s']:.3f} s   throughput: {res['pairs_per_s'] / 1e6:.2f} M pairs/s "
          f"({1e9 / res['pairs_per_s']:.0f} ns per pair)")
    print(f"hits: {res['hits']:,} ({100.0 * res['hits'] / res['n_pairs']:.1f} %)")
    print("case  pairs       share  meaning")
    for k, v in sorted(res["case_counts"].items()):
        print(f"{k:>4}  {v:>10,}  {100.0 * v / res['n_pairs']:5.1f} %  {CASES[k][:70]}")
    return 0


def _experiment(args):
    from .experiment import format_summary, run_experiment, write_experiment

    res = run_experiment(args.prism, vertices=args.vertices, plant=args.plant, duration=args.duration, dt=args.dt,
                         max_speed=args.max_speed, mass=args.mass, damping=args.damping, detach_tol=args.detach_tol,
                         fcl=not args.no_fcl)
    for line in format_summary(res):
        print(line)
    if args.out is None:
        print("(no files written: pass --out DIR for the trajectory CSV, JSON metadata, Markdown summary and figures)")
        return 0
    try:
        paths = write_experiment(res, args.out, figures=not args.no_figures)
    except ImportError as exc:
        print(f"prismbatch: error: {exc} (or pass --no-figures)", file=sys.stderr)
        return 2
    print(f"wrote {paths['csv']}, {paths['json']}, {paths['markdown']}")
    for f in paths["figures"]:
        print(f"wrote {f}")
    return 0


def build_parser():
    """The argument parser (exposed for documentation and tests)."""
    p = argparse.ArgumentParser(
        prog="prismbatch",
        description="Batched collision detection between convex semi-infinite prisms.")
    p.add_argument("--version", action="version", version=f"prismbatch {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    d = sub.add_parser("demo", help="collide a batch of random pose pairs and print throughput and case counts",
                       description="Collide random pose pairs of the paper's scene (pentagon-sized a, "
                                   "hexagon-sized b, both regular n-gons) and print throughput and case counts.")
    d.add_argument("--pairs", type=int, default=1_000_000, help="number of pose pairs (default: 1,000,000)")
    d.add_argument("--vertices", type=int, default=360, help="vertices of each end face (default: 360)")
    d.add_argument("--distribution", choices=["facing", "free"], default="facing",
                   help="pose distribution: the paper's facing scene or uniform random (default: facing)")
    d.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    d.add_argument("--threads", type=int, default=0,
                   help="1 for the serial kernel, k > 1 for k threads, 0 for all of Numba's threads (default: 0)")
    d.add_argument("--contact", action="store_true", help="also compute contact points")
    d.add_argument("--no-progress", action="store_true", help="no progress bar")
    d.set_defaults(func=_demo)
    e = sub.add_parser("experiment", help="simulate the paper's manipulation experiment (Sec. VI-B) with detach control",
                       description="Simulate the paper's experiment: b (a 1.5 mm protective cylinder) is driven by a "
                                   "PD attraction from dC = [2551, -2780, -1970] um to [0, 0, 1000] um past prism a; "
                                   "collisions trigger the detach controller for one step. Prints the case sequence, "
                                   "collisions, contact classes, whether the goal is reached, and the detection cost "
                                   "against python-fcl on the same trajectory. See prismbatch/experiment.py.")
    e.add_argument("--prism", choices=sorted(PRISMS), default="square",
                   help="object a: square prism, side 3 mm, or triangular prism, side 2.8 mm (default: square)")
    e.add_argument("--vertices", type=int, default=3600, help="vertices of b's end face (default: 3600)")
    e.add_argument("--plant", choices=list(PLANTS), default="velocity",
                   help="velocity: the stage follows the commanded velocity; force: m dv/dt = u - c v "
                        "(default: velocity)")
    e.add_argument("--duration", type=float, default=20.0, help="simulated time in s (default: 20)")
    e.add_argument("--dt", type=float, default=0.02, help="sampling period in s (default: 0.02)")
    e.add_argument("--max-speed", type=float, default=None,
                   help="limit the PD command to this speed in mm/s (default: no limit)")
    e.add_argument("--mass", type=float, default=0.1, help="force plant: mass in kg (default: 0.1)")
    e.add_argument("--damping", type=float, default=1.0, help="force plant: viscous friction in mN s/mm (default: 1)")
    e.add_argument("--detach-tol", type=float, default=None, metavar="MM",
                   help="tolerance (mm) for classifying the contact point on a's features "
                        "(default: the distance b moved in the last step)")
    e.add_argument("--out", default=None, metavar="DIR",
                   help="write CSV, JSON, Markdown and figures (PNG, SVG) to DIR (default: print only)")
    e.add_argument("--no-figures", action="store_true", help="with --out: skip the figures (no matplotlib needed)")
    e.add_argument("--no-fcl", action="store_true", help="skip the python-fcl timing")
    e.set_defaults(func=_experiment)
    return p


def main(argv=None):
    """Entry point of the ``prismbatch`` console command."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        if getattr(args, "threads", 0) > 1:
            import numba

            numba.set_num_threads(args.threads)  # raises ValueError above the available threads
        return args.func(args)
    except (ValueError, TypeError) as exc:
        print(f"prismbatch: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
