"""The study's fixed data: the paper's numbers, the scene, the method keys and the default sizes."""

from __future__ import annotations

#: Where the paper's numbers come from.
PAPER_SOURCE = (
    "Efficient Collision Detection and Detach Control for Convex Prisms in Precision "
    "Manipulation: Table I (3600-vertex end faces, Intel i3 3.30 GHz, average ms per query, "
    "100 poses per case) and Sec. VI-A / Fig. 7 (growth per 1000 vertices)"
)

#: The paper's Table I, ms per query at 3600 vertices, cases 1-9.
PAPER_TABLE1_MS = {
    "projection": dict(zip(range(1, 10), (0.03, 0.10, 0.17, 0.31, 0.09, 0.55, 0.12, 0.20, 0.29))),
    "swift": dict(zip(range(1, 10), (5.03, 4.96, 5.02, 5.06, 4.99, 4.95, 5.01, 5.09, 4.91))),
}
#: The paper's fitted growth (Fig. 7c), ms per 1000 vertices; ratio 2.8 %.
PAPER_GROWTH_MS_PER_1000 = {"projection": 0.037, "swift": 1.3}
#: Vertex count of the paper's Table I.
PAPER_TABLE_VERTICES = 3600
#: Vertex counts of the paper's Fig. 7.
PAPER_VERTICES = (36, 180, 360, 1800, 3600)
#: The cases of the paper's Table I (10 and 11 are this package's additions).
PAPER_CASES = tuple(range(1, 10))

#: The scene of the paper's Fig. 6: circumradii of a and b.
RADIUS_A = 2.0
RADIUS_B = 2.5

#: Method keys of the single-query series and what they time.
METHODS = {
    "prismbatch": "Collider.collide_pair, one call per pair",
    "prismbatch_batch1": "Collider.collide on a batch of one pair",
    "fcl": "python-fcl: setTransform x2 + collide, fresh request/result",
    "coal": "coal: setTransform x2 + collide, fresh request/result",
}
PEERS = ("fcl", "coal")

#: Defaults of the full study and of ``quick=True``.
DEFAULTS = dict(vertices=(36, 180, 360, 1800, 3600, 7200), poses_per_case=300, repeats=5, batch_pairs=100_000)
QUICK = dict(vertices=(36, 360, 1800, 3600), poses_per_case=100, repeats=3, batch_pairs=20_000)
