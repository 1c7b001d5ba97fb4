"""Architecture rules: the engine never loads the lab or optional packages; kernels compile anywhere."""

import os
import subprocess
import sys
import textwrap

import pytest

OPTIONAL = ("matplotlib", "fcl", "coal", "dask", "distributed", "tqdm", "highspy")


def _run(code, **env):
    return subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)],
        capture_output=True,
        text=True,
        timeout=600,
        env={**os.environ, **env},
    )


def test_import_loads_no_lab_module_and_no_optional_package():
    out = _run(f"""
        import sys
        import prismbatch, prismbatch.control, prismbatch.planar, prismbatch.sampling
        lab = sorted(m for m in sys.modules if m.startswith("prismbatch.lab"))
        extra = sorted(m for m in {OPTIONAL!r} if m in sys.modules)
        print(lab, extra)
    """)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[] []"


def test_the_cli_loads_lab_modules_only_for_their_subcommand():
    out = _run("""
        import sys
        import prismbatch.cli
        print(sorted(m for m in sys.modules if m.startswith("prismbatch.lab")))
    """)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"


@pytest.mark.slow
def test_unwritable_numba_cache_falls_back_to_no_cache():
    # A shared or container install: neither NUMBA_CACHE_DIR nor the package's
    # own folder can be written, so Numba finds no cache locator (simulated
    # here by removing them all: as root every folder is writable).
    out = _run("""
        from numba.core import caching
        caching.CacheImpl._locator_classes = []
        import numpy as np
        import prismbatch as pb
        a = pb.Prism.regular(5, 2.0)
        r = pb.collide(a, a, np.zeros(3), np.diag([1.0, -1.0, -1.0]), [[0, 0, 1.0], [0, 0, -0.5]], np.eye(3))
        print(r.hit.tolist())
    """)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[False, True]"
    lines = [ln for ln in out.stderr.splitlines() if ln.startswith("prismbatch: Numba cannot write its cache")]
    assert len(lines) == 1, out.stderr
