"""Detach contact classes on random colliding pairs: collide's contact point against distance's witness.

The issue asks where random colliding pairs are classified before and after
``detach`` learned to take a :class:`prismbatch.DistanceResult`: collide's
contact point is some point within tol of both bodies (inside both for deep
contacts, class 6), the witness point on a is where the bodies really touch.

    python benchmarks/detach_classes.py [--pairs 10000] [--seed 0]

Prints, per pose family, the count of each class (0..6) for both inputs.
"""

import argparse

import numpy as np

import prismbatch as pb
from prismbatch.control import CONTACT_CLASSES, detach
from prismbatch.sampling import facing_poses, free_poses


def classes(a, b, P):
    """Class counts (0..6) of the colliding pairs of P, from collide's point and from distance's witness."""
    r = pb.collide(a, b, *P, contact=True)
    d = pb.distance(a, b, *P, witness=True)
    hit = r.hit & (d.status <= 0)  # pairs both call contacts (they differ only inside the touching band)
    sub = [x[hit] if len(x) > 1 else x for x in P]
    err = np.ones((int(hit.sum()), 3))
    before = detach(
        a, r.contact[hit], sub[0], sub[1], sub[3], err, tol=d.tol[hit]
    )  # the same pair tolerance as collide
    after = detach(a, d[hit], sub[0], sub[1], sub[3], err, tol=d.tol[hit])
    count = lambda res: np.bincount(res.contact_class, minlength=7).tolist()
    return int(hit.sum()), count(before), count(after)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", type=int, default=10000, help="pose pairs per family (default: 10000)")
    ap.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    args = ap.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    a, b = pb.Prism.regular(12, 2.0), pb.Prism.regular(36, 1.5)
    print(f"a: 12-gon radius 2, b: 36-gon radius 1.5, {args.pairs} pairs per family, seed {args.seed}")
    print("classes: " + "; ".join(f"{k} {v}" for k, v in CONTACT_CLASSES.items()), flush=True)
    for name, poses in (("facing", facing_poses), ("free", free_poses)):
        n, before, after = classes(a, b, poses(args.pairs, rng))
        print(f"{name:7s} {n:6d} colliding  collide point: {before}  distance witness: {after}")


if __name__ == "__main__":
    main()
