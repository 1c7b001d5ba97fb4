"""Fixtures and the Numba cache of the prismbatch test suite.

* The generators (polygons, rotations, pose sets, pair tolerances) are plain
  functions in ``tests/helpers.py``; ``tests/reference.py`` holds the plain
  references. ``tests/`` is put on ``sys.path`` so that test modules anywhere
  below it can ``from helpers import ...`` and ``from reference import ...``.
* Tests mirror the package: ``tests/engine`` (what users import) and
  ``tests/lab`` (the research applications). Markers: ``slow`` (whole runs,
  subprocesses, LP references on thousands of pairs), ``needs_fcl``,
  ``needs_coal``. ``python -m pytest -m "not slow" tests/engine`` runs the fast engine tests (each
  kernel against its plain reference on a light set; the slow ones repeat it on more and harder pairs).
"""

from __future__ import annotations

import os
import sys
import tempfile


def _kernel_cache_dir():
    """The test suite's own Numba cache folder, apart from the user's.

    Each cached kernel is keyed by the sources of all kernels (``prismbatch/_kernels/jit.py``), so an
    edit anywhere in them compiles anew instead of testing old code. Set before prismbatch (and numba)
    is imported.
    """
    return os.path.join(tempfile.gettempdir(), "prismbatch-numba-tests")


os.environ.setdefault("NUMBA_CACHE_DIR", _kernel_cache_dir())
import pytest  # noqa: E402

TESTS_DIR = os.path.dirname(os.path.abspath(__file__))
if TESTS_DIR not in sys.path:  # test modules import helpers and reference from here
    sys.path.insert(0, TESTS_DIR)

import numpy as np  # noqa: E402

from helpers import concat_pairs, hash_str, make_pairs  # noqa: E402


@pytest.fixture(scope="session")
def pairs_with_margins():
    """~1600 facing + free pairs (small/medium polygons) with LP margins.

    Shared by the invariance tests (which need pairs away from the touching
    band) so the LP reference is run once per session.
    """
    rng = np.random.default_rng(20240611)
    parts = [
        make_pairs(rng, 800, "facing", "smallmed", with_margin=True),
        make_pairs(rng, 800, "free", "smallmed", with_margin=True),
    ]
    return concat_pairs(*parts)


@pytest.fixture
def rng(request):
    """A generator seeded from the test's node id (stable across runs)."""
    seed = abs(hash_str(request.node.nodeid)) % (2**32)
    return np.random.default_rng(seed)
