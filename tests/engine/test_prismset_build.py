"""PrismSet's bulk build (polygons checked in stacks of equal vertex count) against one prism at a time."""

import numpy as np
import pytest

import prismbatch as pb

FIELDS = ("offsets", "vx", "vy", "edge_angle", "edge_table", "vertex_angle", "inv_edge_len", "radius", "centre")


def _polygons(rng, m):
    """Random convex polygons of 3-30 vertices, every size and offset, in every accepted form."""
    out = []
    for _ in range(m):
        k = int(rng.integers(3, 30))
        ang = np.sort(rng.uniform(0, 2 * np.pi, k))
        size = 10.0 ** rng.uniform(-6, 6)
        # an offset of up to 1e4 sizes: rounding far out would dent the denser outlines
        xy = (np.column_stack([np.cos(ang), np.sin(ang)]) + 10.0 ** rng.uniform(-3, 4) * rng.normal(size=2)) * size
        form = rng.integers(6)
        if form == 1:
            xy = xy[::-1]  # clockwise
        elif form == 2:
            xy = np.vstack([xy, xy[:1]])  # closed ring
        elif form == 3:
            xy = xy.tolist()
        elif form == 4:
            xy = pb.Prism(xy)
        elif form == 5:
            reg = 2 * np.pi * np.arange(min(k, 12)) / min(k, 12)  # integer vertices of a regular polygon
            xy = np.round(1000 * np.column_stack([np.cos(reg), np.sin(reg)])).astype(np.int64)
        out.append(xy)
    return out


def _one_at_a_time(polygons):
    """The reference: each polygon made a Prism alone, and the sets of one concatenated."""
    sets = [
        pb.PrismSet([p if isinstance(p, pb.Prism) else pb.Prism(p, name=f"polygon {k}")])
        for k, p in enumerate(polygons)
    ]
    ref = {k: np.concatenate([getattr(s, k) for s in sets]) for k in FIELDS if k != "offsets"}
    ref["offsets"] = np.concatenate(([0], np.cumsum([len(s.vx) for s in sets])))
    return sets, ref


@pytest.mark.parametrize("seed", [0, 1])
def test_bulk_build_equals_one_prism_at_a_time_to_the_bit(seed):
    polygons = _polygons(np.random.default_rng(seed), 300)
    sets, ref = _one_at_a_time(polygons)
    s = pb.PrismSet(polygons)
    for k in FIELDS:
        assert getattr(s, k).dtype == ref[k].dtype, k
        np.testing.assert_array_equal(getattr(s, k), ref[k], err_msg=k)
    for p, one in zip(s.prisms, sets):
        np.testing.assert_array_equal(p.xy, one[0].xy)
        np.testing.assert_array_equal(p.centre, one[0].centre)
        assert p.radius == one[0].radius
        assert not p.xy.flags.writeable


def test_prisms_are_made_on_access_as_a_sequence_gives_them():
    polygons = _polygons(np.random.default_rng(2), 60)
    s = pb.PrismSet(polygons)
    assert len(s) == 60
    for k in (0, 17, 59, -1, -60):
        p, ref = s[k], polygons[k]
        assert s[k] is p  # made once
        if isinstance(ref, pb.Prism):
            assert p is ref  # a Prism given is the Prism kept
        else:
            np.testing.assert_array_equal(p.xy, pb.Prism(ref).xy)
            assert p.radius == pb.Prism(ref).radius
    assert [p.n_vertices for p in s[10:20:3]] == [s[k].n_vertices for k in range(10, 20, 3)]
    assert len(s.prisms) == 60 and s.prisms[5] is s[5]
    for k in (60, -61):
        with pytest.raises(IndexError):
            s[k]
    with pytest.raises(TypeError):
        s[1.0]
    with pytest.raises(ValueError):
        s[3].xy[0, 0] = 1.0  # read-only, as a Prism's vertices are


BAD = [
    ([[0, 0], [1, 0], [1, 0], [0, 1]], ValueError, "vertex 2 repeats vertex 1"),
    ([[0, 0], [1, 0], [2, 0]], ValueError, "zero area"),
    ([[0, 0], [2, 0], [1, 0.1], [1, 1]], ValueError, "not convex at vertex 2"),
    ([[0, 0], [1, 1], [1, 0], [0, 1]], ValueError, "zero area"),  # a bow tie
    ([[0, 0], [2, 0], [2, 2], [0, 2], [1.5, -1], [3, 1]], ValueError, "self-intersecting"),
    ([[0, 0], [2, 0], [2, 2], [1, 1.5], [0, 2]], ValueError, "not convex at vertex 3"),
    ("abc", TypeError, "real numbers"),
    ([[0, 0], [1, 0]], ValueError, "at least 3 vertices"),
    ([[0, 0], [1, 0], [np.nan, 1]], ValueError, "vertex 2 is not finite"),
    ([[0, 0], [1, 0], [1, 1e-13]], ValueError, "too thin"),
    (np.zeros((4, 2)), ValueError, "all 4 vertices coincide"),  # (not a ring closed by the 4th: the count given)
    ([[0, 0], [1, 0], [1 + 1e-17, 1e-17], [0, 1]], ValueError, "edge 1 is"),
    ([[0, 0], [1, 0], [0, 1, 2]], ValueError, "could not be read"),
]


@pytest.mark.parametrize("bad, kind, words", BAD)
@pytest.mark.parametrize("where", [0, 4])
def test_the_first_bad_polygon_in_order_is_named(bad, kind, words, where):
    good = [[0, 0], [1, 0], [0, 1]]
    later_bad = [[0, 0], [1, 0], [0.5, 0.5], [0.5, 0.5]]  # a later, different error must not be reported
    polygons = [good] * 6
    polygons.insert(where, bad)
    polygons.insert(where + 2, later_bad)
    with pytest.raises(kind, match=words) as got:
        pb.PrismSet(polygons)
    assert str(got.value).startswith(f"polygon {where}:")
    with pytest.raises(kind) as alone:  # the same words as the polygon checked alone
        pb.Prism(bad, name=f"polygon {where}")
    assert str(alone.value) == str(got.value)
