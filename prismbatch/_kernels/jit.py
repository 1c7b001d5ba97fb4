"""How prismbatch compiles: one place fixes the Numba options.

Every kernel is ``@jit(...)``: ``njit`` with an on-disk cache, falling back
to no cache (one line on stderr) where the cache folder is not writable
(shared installs, containers, a read-only ``NUMBA_CACHE_DIR``). A loop over
pairs is written once and compiled as serial and parallel twins
(:func:`twins`), as umap does. Nothing here changes Numba's global config.
"""

import functools
import hashlib
import sys
import threading
import types
from pathlib import Path

from numba import njit
from numba.core.caching import FunctionCache

__all__ = ["jit", "twins", "per_dtype", "cache_enabled", "first_call"]

_cache = {"ok": None}  # None: not tried yet


def cache_enabled():
    """True once a kernel was compiled with the on-disk cache, False after the fallback, None before."""
    return _cache["ok"]


@functools.cache
def kernel_sources():
    """A digest of every kernel module's source (this folder's ``*.py``) and of ``config.py`` (whose
    constants the kernels compile in), part of every cached kernel's key (:class:`_SourcesKeyedCache`);
    read once, at the first load from or save to the cache."""
    h = hashlib.sha256()
    here = Path(__file__).resolve().parent
    for path in [*sorted(here.glob("*.py")), here.parent / "config.py"]:
        h.update(path.name.encode())
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


class _SourcesKeyedCache(FunctionCache):
    """Numba's on-disk cache with :func:`kernel_sources` in each entry's key.

    Numba keys an entry by the function's own bytecode and its file's time stamp, not by the kernels
    it calls from other modules, which it compiles in: after a ``git pull`` into an editable install
    (or any edit), a kernel whose file did not change would load with the old code of a callee whose
    file did, and run it silently. Keyed by every kernel's source, it compiles anew instead.
    """

    def _index_key(self, sig, codegen):
        return (*super()._index_key(sig, codegen), kernel_sources())


def _key_by_sources(dispatcher):
    """``dispatcher`` with :class:`_SourcesKeyedCache` in place of Numba's cache (kept if Numba's
    internals differ from what this expects: the cache then works as Numba's does)."""
    try:
        if isinstance(dispatcher._cache, FunctionCache):
            dispatcher._cache = _SourcesKeyedCache(dispatcher.py_func)
    except (AttributeError, TypeError):  # pragma: no cover - another Numba's internals
        pass
    return dispatcher


def jit(func=None, *, refcounts=False, **options):
    """``numba.njit(cache=True, **options)``, without the cache where it cannot be written.

    Usable as ``@jit`` or ``@jit(inline="always")``. No ``fastmath``: the
    kernels rely on NaN and inf behaving as IEEE says.

    Compiled without Numba's reference counting of arrays (its ``_nrt``
    option) unless ``refcounts=True``, which the functions that allocate
    arrays or return them take. Counting costs atomic increments and
    decrements on every array handed to a call (about 90 ns per pair in the
    collide loop, half the time of a distance query), and a callee inherits
    it: Numba compiles a function once per signature, with the flags of the
    first caller in the process (or of the compile its disk cache kept), so
    a helper first reached from a counting kernel counted references in
    every kernel that called it later, and the speed of a loop depended on
    which call came first. A function compiled without it that allocates
    fails to compile ("NRT required but not enabled"); one that returned an
    array would hand its caller a reference it does not own, so none does
    (a test checks the compiled signatures).

    A kernel that several paths call is compiled once per signature, and Numba
    types a constant argument (``True``, ``False``, ``0``) as a literal: each
    such call site compiled the callee and everything it calls once more. Pass
    constants to shared kernels as ``np.bool_(...)`` / ``np.int64(...)``, and
    arrays in the layout the batch kernels pass (C-contiguous, writeable);
    ``tests/engine/test_structure.py`` checks the shared callees' signatures.
    """
    if not refcounts:
        options["_nrt"] = False

    def compile_(f):
        if _cache["ok"] is not False:
            try:
                out = njit(cache=True, **options)(f)
            except RuntimeError as exc:  # "cannot cache function ...: no locator available for file ..."
                if "locator" not in str(exc):
                    raise
                _cache["ok"] = False
                print(
                    f"prismbatch: Numba cannot write its cache ({exc}); compiling without it "
                    f"(set NUMBA_CACHE_DIR to a writable folder to keep compiled kernels)",
                    file=sys.stderr,
                )
            else:
                _cache["ok"] = True
                return _key_by_sources(out)
        return njit(cache=False, **options)(f)

    return compile_ if func is None else compile_(func)


def twins(loop, name, **options):
    """``(serial, parallel)``: ``loop`` compiled with ``parallel=False`` and ``True``.

    Each twin is compiled from a copy of ``loop`` under its own name
    (``name + "_serial"`` / ``"_parallel"``): Numba's on-disk cache is keyed
    by the function's name and source line, not by the ``parallel`` flag, so
    under one name the twins would overwrite each other's cache entry and
    one would silently run as the other.
    """
    return (
        jit(parallel=False, **options)(_renamed(loop, name + "_serial")),
        jit(parallel=True, **options)(_renamed(loop, name + "_parallel")),
    )


def per_dtype(func, name, dtypes, **options):
    """``{numpy.dtype: dispatcher}``: ``func`` compiled once per dtype, each copy under its own
    name (``name + "_" + dtype name``) so that each can be closed to new signatures on its own."""
    import numpy as np

    return {np.dtype(d): jit(**options)(_renamed(func, f"{name}_{np.dtype(d).name}")) for d in dtypes}


def _renamed(func, name):
    """A copy of ``func`` under another name."""
    renames = {"co_name": name}
    if sys.version_info >= (3, 11):  # co_qualname is new in 3.11
        renames["co_qualname"] = name
    code = func.__code__.replace(**renames)
    g = types.FunctionType(code, func.__globals__, name, func.__defaults__, func.__closure__)
    g.__qualname__ = name
    g.__doc__ = func.__doc__
    return g


#: Seconds a first call may take before a notice says that it is compiling.
COMPILE_NOTICE_AFTER_S = 1.0
_called = set()  # keys of the calls made once in this process
_notice = {"shown": False}  # once per process: the kernels of one run compile one after another


def _compile_notice():
    if _notice["shown"]:
        return
    _notice["shown"] = True
    print(
        "prismbatch: compiling the collision kernels for this process's first call (once; about 7 to 30 s on a "
        "2-core machine, by path and load; later runs load them from Numba's cache)",
        file=sys.stderr,
        flush=True,
    )


def first_call(key, kernel, *args):
    """``kernel(*args)``; the first time ``key`` is called in this process, a one-line notice goes
    to stderr if the call (compilation or cache load) takes more than :data:`COMPILE_NOTICE_AFTER_S`
    (at most one notice per process).

    A cold compile takes seconds and would otherwise look like a hang; a load from the
    cache is faster than the notice's delay and stays silent.
    """
    if key in _called:
        return kernel(*args)
    timer = threading.Timer(COMPILE_NOTICE_AFTER_S, _compile_notice)
    timer.daemon = True
    timer.start()
    try:
        return kernel(*args)
    finally:
        timer.cancel()
        _called.add(key)
