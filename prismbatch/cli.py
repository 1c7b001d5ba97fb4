"""The ``prismbatch`` command line."""

from __future__ import annotations

import argparse
import sys

from . import __version__


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
