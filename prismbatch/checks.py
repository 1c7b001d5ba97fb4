"""Argument checks shared by the engine and the lab: real scalars, flags, numeric arrays, and memory.

Each raises a TypeError or ValueError that names the argument. A size that cannot
fit (a billion-vertex polygon, a simulation of years in milliseconds) is refused
with one ValueError naming what needs the memory and how much, before anything is
allocated, instead of driving the machine out of memory.
"""

from __future__ import annotations

import os

import numpy as np

__all__ = [
    "available_memory",
    "check_memory",
    "format_bytes",
    "as_real_array",
    "refuse_masked",
    "real_scalar",
    "check_flag",
    "indexed_name",
]

#: Requests below this are never refused and cost no system call (reading
#: /proc/meminfo takes ~15 µs, a seventh of building a small Prism).
_ALWAYS_FITS = 64 * 2**20


def available_memory():
    """Bytes of memory available to a new allocation, or None if the OS does not say.

    Linux: ``MemAvailable`` of /proc/meminfo (free memory plus the caches the
    kernel can drop). Elsewhere: free physical pages
    (``os.sysconf("SC_AVPHYS_PAGES")``) times the page size.
    """
    try:
        with open("/proc/meminfo", "rb") as f:
            for line in f:
                if line.startswith(b"MemAvailable:"):
                    return int(line.split()[1]) * 1024  # the kernel writes kibibytes as "kB"
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (AttributeError, ValueError, OSError):  # no sysconf, or the name is unknown here (macOS)
        return None


def format_bytes(nbytes):
    """``nbytes`` as text in decimal units: "512.0 MB", "48.0 GB", "3.2 TB"."""
    for unit, size in (("TB", 1e12), ("GB", 1e9)):
        if nbytes >= size:
            return f"{nbytes / size:.1f} {unit}"
    return f"{nbytes / 1e6:.1f} MB"


def check_memory(nbytes, what):
    """Raise ValueError if ``nbytes`` is more than the memory available.

    Parameters
    ----------
    nbytes : int or float
        Bytes the allocation needs (an estimate; a float, so that an absurd
        size cannot overflow before it is refused).
    what : str
        What needs it, as the message starts: ``"Prism.regular(1000000000)"``.

    Raises
    ------
    ValueError
        ``"<what>: needs about 48.0 GB, more than the 21.3 GB of memory
        available"``. Never raised below 64 MiB, nor when the OS does not
        report its available memory (:func:`available_memory` is None).
    """
    if not nbytes > _ALWAYS_FITS:
        return
    avail = available_memory()
    if avail is not None and nbytes > avail:
        raise ValueError(
            f"{what}: needs about {format_bytes(nbytes)}, more than the {format_bytes(avail)} of memory available"
        )


def indexed_name(name: str, i: int | None) -> str:
    """``name`` for a single item, ``name[i]`` for an item of a batch."""
    return name if i is None else f"{name}[{i}]"


def refuse_masked(x, name: str) -> None:
    """ValueError if ``x`` is a numpy masked array with masked entries (or a list or tuple of such rows).

    ``np.asarray`` drops the mask and keeps the values under it, so a masked pose or vertex would be
    computed with as if it were data. An unmasked ``MaskedArray`` is read as its data.
    """
    masked = isinstance(x, np.ma.MaskedArray) and np.ma.is_masked(x)
    if isinstance(x, (list, tuple)):  # rows given as a list of masked arrays
        masked = any(isinstance(e, np.ma.MaskedArray) and np.ma.is_masked(e) for e in x)
    if masked:
        raise ValueError(
            f"{name} has masked entries (numpy.ma), which would be read as the values under the mask; pass "
            f"a plain array of the values you mean (np.ma.compress_rows drops masked rows, .filled(v) fills them)"
        )


def as_real_array(x, name: str) -> np.ndarray:
    """``np.asarray`` that rejects non-real-numeric data and masked entries with a named error."""
    refuse_masked(x, name)
    try:
        arr = np.asarray(x)
    except ValueError as exc:
        # Ragged nested lists: numpy's own message does not say which argument.
        raise ValueError(f"{name} could not be converted to an array: {exc}") from exc
    # Only signed/unsigned integers and floats.  bool is excluded on purpose:
    # a boolean "rotation" is almost certainly a mask passed by mistake.
    if arr.dtype.kind not in "iuf":
        raise TypeError(f"{name} must have a real numeric dtype (integer or float), got dtype {arr.dtype}")
    return arr


_FLOAT_MAX = float(np.finfo(np.float64).max)


def real_scalar(x, name: str, lo: float = -_FLOAT_MAX, hi: float = _FLOAT_MAX) -> float:
    """``x`` as a finite float in [lo, hi].

    A real number or 0-d array of one; TypeError for strings, bools, None and
    other non-numbers, ValueError for arrays of another shape, NaN, inf and
    values out of range.
    """
    refuse_masked(x, name)
    a = None if isinstance(x, (str, bytes, bool, np.bool_)) else np.asarray(x)
    if a is None or a.dtype.kind not in "iuf":
        raise TypeError(f"{name} must be a real number, got {type(x).__name__} {x!r}")
    if a.ndim != 0:
        raise ValueError(f"{name} must be a scalar, got shape {a.shape}")
    v = float(a)
    if not lo <= v <= hi:  # also NaN
        rng = "finite" if lo == -_FLOAT_MAX else f"finite and >= {lo:g}"
        raise ValueError(f"{name} must be {rng if hi == _FLOAT_MAX else f'in [{lo:g}, {hi:g}]'}, got {v!r}")
    return v


def is_int(x) -> bool:
    """A Python or NumPy integer, not a bool."""
    return not isinstance(x, (bool, np.bool_)) and isinstance(x, (int, np.integer))


def integer(x, name: str, lo: int, hi: int | None = None) -> int:
    """``x`` as a Python int in [lo, hi]: TypeError unless it is an integer (a bool, a float such
    as 2.0 or a string is not), ValueError out of range (``hi`` None: no upper end)."""
    if not is_int(x):
        raise TypeError(f"{name} must be an integer, got {type(x).__name__} {x!r}")
    if x < lo or (hi is not None and x > hi):
        raise ValueError(f"{name} must be {f'>= {lo}' if hi is None else f'in [{lo}, {hi}]'}, got {x}")
    return int(x)


def check_flag(x, name: str, *, allow_none: bool = False) -> None:
    """TypeError unless ``x`` is a bool (or None where allowed): a string such as 'no' is not False."""
    if not (isinstance(x, (bool, np.bool_)) or (allow_none and x is None)):
        allowed = "True, False or None" if allow_none else "True or False"
        raise TypeError(f"{name} must be {allowed}, got {type(x).__name__} {x!r}")
