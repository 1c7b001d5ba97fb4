"""Checkpoints of long runs: each finished unit of work is one file in the output folder.

A run that stops (Ctrl-C, SIGTERM, a crash, a lost machine) keeps every unit it finished;
the same command with ``--resume`` and the same ``--out`` loads them instead of recomputing
them. Because the units are deterministic functions of the run's settings (validation
chunks are regenerated from the seed), a resumed run's counts equal an uninterrupted one's.

Layout: ``OUT/checkpoint/<command>/run.json`` (the settings that must match) and one
``<unit>.pickle`` per finished unit, each written atomically (:func:`~prismbatch.lab.report.atomic_open`).
The folder is removed once the run's own files are written. The pickles are the run's own
output, read back by the same user: they are not meant to be exchanged.
"""

from __future__ import annotations

import json
import pickle
import shutil
import warnings
from pathlib import Path

from .report import atomic_open, jsonable, write_json

__all__ = ["Checkpoint", "Interrupted", "run_unit", "discard", "resumed_note"]


class Interrupted(KeyboardInterrupt):
    """A run stopped by SIGINT or SIGTERM after saving what it finished.

    Attributes
    ----------
    done, total : int
        Units of work finished (including any loaded on resume) and in all.
    unit : str
        What a unit is ("pair", "vertex count", ...), for the message.
    checkpoint : Checkpoint or None
        Where the finished units are kept.
    files : dict
        The partial report's files, when one was written.
    """

    def __init__(self, done, total, unit, *, checkpoint=None, files=None):
        super().__init__(f"interrupted after {done:,} of {total:,} {unit}s")
        self.done, self.total, self.unit = done, total, unit
        self.checkpoint, self.files = checkpoint, files or {}


class Checkpoint:
    """The finished units of one run in ``out_dir/checkpoint/<command>/``.

    Parameters
    ----------
    out_dir : str or path-like
        The run's output folder (``--out``).
    command : str
        The command's name (one folder per command, so that ``study`` and ``validate``
        can share an output folder).
    settings : dict
        Everything the units depend on; a resumed run must have the same.
    resume : bool
        Load the units a previous run with the same settings finished. Without it, an old
        checkpoint is discarded and the run starts from scratch.

    Raises
    ------
    ValueError
        ``resume`` with a checkpoint written by a run with other settings (the message names
        the settings that differ).
    """

    def __init__(self, out_dir, command, settings, *, resume=False):
        self.dir = Path(out_dir) / "checkpoint" / command
        self.settings = jsonable(settings)
        manifest = self.dir / "run.json"
        if resume and manifest.exists():
            with open(manifest, encoding="utf-8") as f:
                old = json.load(f)["settings"]
            differ = sorted(k for k in set(old) | set(self.settings) if old.get(k) != self.settings.get(k))
            if differ:
                raise ValueError(
                    f"--resume: the checkpoint in {self.dir} was written with other settings "
                    f"({', '.join(differ)}); run the same command, or drop --resume to start again"
                )
        elif self.dir.exists():
            shutil.rmtree(self.dir)
        write_json(manifest, {"command": command, "settings": self.settings})

    def _path(self, unit):
        return self.dir / f"{unit}.pickle"

    def load(self, unit):
        """The saved result of ``unit``, or None when it was not finished, or its file cannot be read
        (cut short or damaged after it was written: the unit is then computed again, with a warning)."""
        p = self._path(unit)
        if not p.exists():
            return None
        try:
            with open(p, "rb") as f:
                return pickle.load(f)
        except (pickle.UnpicklingError, EOFError, AttributeError, ImportError, IndexError, TypeError) as exc:
            warnings.warn(f"checkpoint {p} cannot be read ({type(exc).__name__}: {exc}); computing it again",
                          RuntimeWarning, stacklevel=2)  # fmt: skip
            return None

    def save(self, unit, result):
        """Save the result of a finished ``unit`` (atomically)."""
        with atomic_open(self._path(unit), "wb") as f:
            pickle.dump(result, f, protocol=pickle.HIGHEST_PROTOCOL)

    def remove(self):
        """Delete the checkpoint (the run finished and wrote its files)."""
        discard(self.dir.parent.parent, self.dir.name)


def discard(out_dir, command):
    """Delete ``command``'s checkpoint in ``out_dir`` (and the checkpoint folder once empty)."""
    folder = Path(out_dir) / "checkpoint"
    shutil.rmtree(folder / command, ignore_errors=True)
    if folder.exists() and not any(folder.iterdir()):
        folder.rmdir()


def run_unit(ckpt, unit, compute):
    """``(compute(), False)``, saved to ``ckpt``; or ``(saved result, True)`` when ``ckpt`` has ``unit``.

    ``ckpt`` None runs ``compute`` without saving.
    """
    if ckpt is not None:
        saved = ckpt.load(unit)
        if saved is not None:
            return saved, True
    result = compute()
    if ckpt is not None:
        ckpt.save(unit, result)
    return result, False


def resumed_note(resumed):
    """Report lines saying which vertex counts a resumed run loaded (none: no lines)."""
    if not resumed:
        return []
    counts = ", ".join(str(n) for n in resumed)
    return [
        f"**Resumed run:** the rows at {counts} vertices were measured by the interrupted run (another "
        "process, perhaps another machine load) and loaded from its checkpoint.",
        "",
    ]
