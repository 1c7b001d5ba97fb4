"""What the batch results share: their length and how they are indexed.

:class:`~prismbatch.CollisionResult`, :class:`~prismbatch.DistanceResult`,
:class:`~prismbatch.TimeOfImpactResult` and :class:`~prismbatch.ProbabilityResult`
are frozen dataclasses whose first field is an (N,) array; :class:`BatchResult`
gives them ``len`` and indexing, so ``result[k]``, ``result[a:b]``,
``result[mask]`` cut every per-pair array the same way and keep the rest.
"""

from __future__ import annotations

import dataclasses

import numpy as np

__all__ = ["BatchResult", "pair_index", "new_result"]


def new_result(cls, fields):
    """``cls(**fields)`` without the frozen dataclass's ``__init__``, which sets each field through
    ``object.__setattr__`` (some 0.3 µs of a one-pair query); fields left out keep their defaults."""
    r = _object_new(cls)
    r.__dict__.update(fields)
    return r


_object_new = object.__new__


def pair_index(k, n):
    """``k`` as an index into ``n`` pairs; an integer is kept as a batch of one (``k:k + 1``).

    Raises
    ------
    IndexError
        An integer out of range.
    TypeError
        A bool or None (``True`` would read as pair 1, ``None`` add an axis to every field), or an index
        of more than one dimension.
    """
    if k is None or isinstance(k, (bool, np.bool_)):
        raise TypeError(f"pairs are selected by an integer, a slice, an index array or a boolean mask, not {k!r}")
    if isinstance(k, tuple):
        raise TypeError(f"pairs are selected along one axis; got the index {k!r}")
    if isinstance(k, (int, np.integer)):
        if not -n <= k < n:
            raise IndexError(f"pair {k} is out of range for {n} pairs")
        k = slice(k, k + 1 if k != -1 else None)
    return k


class BatchResult:
    """Mixin of the result dataclasses: ``len`` (the first field's rows) and indexing."""

    def __len__(self):
        return getattr(self, dataclasses.fields(self)[0].name).shape[0]

    def __getitem__(self, k):
        """The result of some pairs: an index, a slice, an index array or a boolean mask
        (an integer keeps a batch of one, like ``result[k:k + 1]``)."""
        n = len(self)
        k = pair_index(k, n)
        cut = {}
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if isinstance(v, np.ndarray) and v.ndim and v.shape[0] == n:  # per pair; scalars and None stay
                cut[f.name] = v[k]
        return dataclasses.replace(self, **cut)
