"""HiGHS (``highspy``, the ``exact`` extra) for the lab's QP references, imported where used.

:func:`new_highs` makes a solver that prints nothing. highspy's constructor prints a licence banner
on the process's standard output the first time in a process (highspy 1.16), before any option can
be set, so that ``prismbatch validate ... > report.txt`` wrote it into the report.
"""

from __future__ import annotations

import os
import sys

__all__ = ["HIGHSPY_MISSING", "import_highspy", "new_highs"]

HIGHSPY_MISSING = "highspy is not installed (the QP of the distance reference): pip install 'prismbatch[exact]'"

_first_made = False  # the banner comes with the first solver of a process only


def import_highspy():
    """The ``highspy`` module; ImportError with the pip command when it is missing."""
    try:
        import highspy  # noqa: PLC0415
    except ImportError as exc:
        raise ImportError(HIGHSPY_MISSING) from exc
    return highspy


def _without_stdout(make):
    """``make()`` with file descriptor 1 pointed at the null device (the banner is written by C++)."""
    sys.stdout.flush()
    try:
        saved = os.dup(1)
    except OSError:  # no standard output to protect
        return make()
    null = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(null, 1)
        return make()
    finally:
        os.dup2(saved, 1)
        os.close(saved)
        os.close(null)


def new_highs(time_limit):
    """A ``highspy.Highs`` with its output off and a time limit in seconds."""
    global _first_made
    highspy = import_highspy()
    h = highspy.Highs() if _first_made else _without_stdout(highspy.Highs)
    _first_made = True
    h.setOptionValue("output_flag", False)
    h.setOptionValue("time_limit", float(time_limit))
    return h
