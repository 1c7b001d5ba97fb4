"""Checks the engine and the lab make before a large allocation.

A size that cannot fit (a billion-vertex polygon, a simulation of years in
milliseconds) is refused with one ValueError naming what needs the memory and
how much, before anything is allocated, instead of driving the machine out of
memory.
"""

from __future__ import annotations

import os

__all__ = ["available_memory", "check_memory", "format_bytes"]

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
