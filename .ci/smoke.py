"""Smoke test for the other CPython versions: import, one batch, one pair, one detach."""

import sys

import numpy as np

import prismbatch as pb

a, b = pb.Prism.regular(5, 2.0), pb.Prism.regular(6, 2.5)
down = np.diag([1.0, -1.0, -1.0])
r = pb.collide(a, b, np.zeros(3), down, [[0, 0, 1.0], [0, 0, 0.0]], np.eye(3), contact=True)
assert r.hit.tolist() == [False, True] and r.case.tolist() == [1, 4], (r.hit, r.case)
p = pb.Collider(a, b).collide_pair(np.zeros(3), down, np.array([0.0, 0.0, -0.5]), np.eye(3))
assert p.hit, p
from prismbatch.control import detach  # noqa: E402

d = detach(a, r.contact[1:], np.zeros(3), down, np.eye(3), np.ones(3))
assert np.isfinite(d.force).all(), d
print(f"smoke OK on Python {sys.version.split()[0]}")
