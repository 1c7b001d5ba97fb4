"""Architecture rules: the engine never loads the lab or optional packages; kernels compile anywhere."""

import os
import subprocess
import sys
import textwrap

import pytest

OPTIONAL = ("matplotlib", "fcl", "coal", "dask", "distributed", "tqdm", "highspy")


def _run(code, cwd=None, **env):
    return subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)],
        capture_output=True,
        text=True,
        timeout=600,
        env={**os.environ, **env},
        cwd=cwd,
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


@pytest.mark.slow
def test_a_cached_kernel_recompiles_when_a_kernel_it_calls_changes(tmp_path):
    # Numba alone would load gjk3d.closest from its cache with the old vec3.dot compiled in: its own
    # file, bytecode and time stamp are unchanged (as after a git pull into an editable install).
    import shutil
    from pathlib import Path

    pkg = tmp_path / "src"
    shutil.copytree(Path(__file__).resolve().parents[2] / "prismbatch", pkg / "prismbatch", copy_function=shutil.copy2)
    call = f"""
        import numpy as np
        from prismbatch._kernels.gjk3d import closest
        W = np.array([[1.0, 0.5, 2.0], [-1.0, 0.5, 2.0], [0.0, -1.0, 2.5]] + [[0.0] * 3] * 5)
        m, vx, vy, vz, _, _ = closest(W, np.zeros((8, 3), np.int64), np.zeros(8), 3)
        assert closest.py_func.__code__.co_filename.startswith({str(pkg)!r})
        print(m, vx.hex(), vy.hex(), vz.hex(), sum(closest.stats.cache_hits.values()))
    """
    env = {"NUMBA_CACHE_DIR": str(tmp_path / "cache"), "PYTHONPATH": str(pkg)}

    def run():
        out = _run(call, cwd=tmp_path, **env)  # not the checkout's folder, whose package -c would import
        assert out.returncode == 0, out.stderr
        *point, hits = out.stdout.split()
        return point, int(hits)

    first, hits = run()
    assert hits == 0
    assert run() == (first, 1)  # the second process loads it from the cache
    vec3 = pkg / "prismbatch" / "_kernels" / "vec3.py"
    src = vec3.read_text()
    assert src.count("return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]") == 1
    vec3.write_text(src.replace("return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]", "return a[0] * b[0] + a[1] * b[1]"))
    changed, hits = run()
    assert hits == 0 and changed != first  # compiled anew, with the new dot
    assert run() == (changed, 1)
    # config.py's constants are compiled into kernels (ROUNDING_ALLOWANCE into the collide loop): an edit
    # there compiles anew too
    config = pkg / "prismbatch" / "config.py"
    config.write_text(config.read_text() + "\n# edited\n")
    assert run() == (changed, 0)


def test_a_slow_first_call_prints_one_compile_notice(capsys, monkeypatch):
    import time

    from prismbatch._kernels import jit

    monkeypatch.setattr(jit, "COMPILE_NOTICE_AFTER_S", 0.05)
    monkeypatch.setattr(jit, "_called", set())
    monkeypatch.setattr(jit, "_notice", {"shown": False})
    slow, fast = object(), object()
    assert jit.first_call(slow, lambda x: (time.sleep(0.3), x)[1], 7) == 7
    assert jit.first_call(fast, lambda: 1) == 1
    assert jit.first_call(slow, lambda: 2) == 2  # a second call: no timer, no notice
    assert jit.first_call(object(), lambda: time.sleep(0.3)) is None  # another slow first call: no second notice
    err = capsys.readouterr().err
    assert err.count("prismbatch: compiling the collision kernels") == 1


def test_collide_reuses_its_collider_only_for_the_same_shapes_and_tolerances():
    import numpy as np

    import prismbatch as pb

    collide_module = sys.modules["prismbatch.collide"]  # the module; pb.collide is the function

    a, b = pb.Prism.regular(5, 2.0), pb.Prism.regular(6, 2.5)
    down = np.diag([1.0, -1.0, -1.0])
    p = np.array([0.0, 0.0, 1e-6])
    for _ in range(2):
        tight = pb.collide(a, b, np.zeros(3), down, p, np.eye(3), rtol=1e-9)
        loose = pb.collide(a, b, np.zeros(3), down, p, np.eye(3), rtol=1e-6)
    assert tight.hit.tolist() == [False] and loose.hit.tolist() == [True]
    assert collide_module.collider_for(a, b, 1e-6, 0.0, np.float64) is collide_module.collider_for(
        a, b, 1e-6, 0.0, "f8"
    )
    assert collide_module.collider_for(a, b, 1e-6, 0.0, np.float64) is not collide_module.collider_for(
        b, a, 1e-6, 0.0, "f8"
    )
    with pytest.raises(TypeError):
        pb.collide(a, b, np.zeros(3), down, p, np.eye(3), rtol=True)


def test_the_kernels_unpack_the_same_fields_the_prism_set_packs():
    # The packed layout (batch.pack / batch.unpack) is read in Python through unpack.py_func and in
    # the kernels through the compiled unpack: both must give the PrismSet's arrays.
    import numpy as np

    import prismbatch as pb
    from prismbatch._kernels.batch import unpack

    s = pb.PrismSet([pb.Prism.regular(5, 1.0), [[0, 0], [3, 0], [0, 2.0]], pb.Prism.regular(40, 1e-3)])
    for dt in (np.float64, np.float32):
        k = s.kernel_arrays(dt)
        # the compiled unpack (what the kernels read) against the Python views ...
        for field, got in zip(k._fields, unpack(k.floats, k.ints)):
            assert np.array_equal(got, getattr(k, field)) and got.dtype == getattr(k, field).dtype, field
        # ... and every field against the PrismSet's own arrays
        for field in ("vx", "vy", "edge_angle", "vertex_angle", "inv_edge_len", "radius", "centre"):
            assert np.array_equal(getattr(k, field), getattr(s, field).astype(dt)), field
        assert np.array_equal(k.edge_table, s.edge_table) and np.array_equal(k.offsets, s.offsets)


def test_kernels_without_refcounts_keep_no_reference_to_their_arguments():
    # The per-pair kernels run without Numba's reference counting (jit(refcounts=False)):
    # arguments must come back with the reference counts they went in with, on every path.
    import numpy as np

    import prismbatch as pb
    from prismbatch.sampling import facing_poses

    col = pb.Collider(pb.Prism.regular(12, 2.0), pb.Prism.regular(7, 2.5))
    poses = [np.ascontiguousarray(x) for x in facing_poses(200, np.random.default_rng(0))]
    one = [x[0].copy() for x in poses]
    col.collide(*poses, parallel=False)
    col.collide(*poses, parallel=True)
    col.collide_pair(*one)
    before = [sys.getrefcount(x) for x in (*poses, *one, col._a.floats, col._b.ints)]
    for _ in range(50):
        col.collide(*poses, parallel=False, contact=True)
        col.collide(*poses, parallel=True)
        col.collide_pair(*one)
    assert [sys.getrefcount(x) for x in (*poses, *one, col._a.floats, col._b.ints)] == before


def _call_every_path():
    """Call every public path once (batch and one pair, float64): what a user's first session compiles.
    Returns the kernel dispatchers, ``(module name, name, dispatcher)``, and how many came from the cache."""
    import importlib
    import pkgutil

    import numpy as np
    from numba.core.registry import CPUDispatcher

    import prismbatch as pb
    import prismbatch._kernels as kernels
    from prismbatch._kernels.batch import unpack
    from prismbatch._kernels.distance import block_of, workspace
    from prismbatch.sampling import free_poses

    a, b = pb.Prism.regular(7, 2.0), pb.Prism.regular(9, 2.5)
    col = pb.Collider(a, b)
    poses = free_poses(64, np.random.default_rng(0), radius=2.5)
    col.collide(*poses, contact=True)
    col.distance(*poses, witness=True)
    col.collide(*poses, margin=0.1)
    col.time_of_impact(*poses, np.ones(3), np.ones(3), horizon=1.0, pose=True, contact=True)
    one = tuple(np.ascontiguousarray(x[0]) for x in poses)
    col.collide_pair(*one)
    col.distance(*one, witness=True)
    col.explain(*one)
    col.collision_probability(np.zeros(3), np.diag([1.0, -1, -1]), [0, 0, 0.3], np.eye(3), np.eye(6) * 1e-3, seed=1)
    unpack(col._a.floats, col._a.ints)
    block_of(workspace(1, 4), 0)
    found, loaded = [], 0
    for info in pkgutil.iter_modules(kernels.__path__):
        mod = importlib.import_module(f"prismbatch._kernels.{info.name}")
        for name, obj in vars(mod).items():
            if isinstance(obj, CPUDispatcher):
                found.append((info.name, name, obj))
                loaded += sum(obj.stats.cache_hits.values())
    return found, loaded


def test_kernels_compiled_without_reference_counting_return_no_arrays():
    # jit compiles without Numba's reference counting unless told otherwise; a function so compiled
    # that returned an array would hand its caller a reference it does not own (freed too early).
    # After the main calls (and the helpers Python calls directly), no such overload returns one.
    from numba.core import types

    def holds_array(t):
        return isinstance(t, types.Array) or (isinstance(t, types.BaseTuple) and any(map(holds_array, t)))

    found, loaded = _call_every_path()
    checked = 0
    for mod, name, obj in found:
        if obj.targetoptions.get("_nrt", True) is False:
            for cres in obj.overloads.values():
                checked += 1
                assert not holds_array(cres.signature.return_type), f"{mod}.{name} returns arrays"
    if checked <= 20 and loaded:
        # A kernel loaded from Numba's cache brings its callees compiled in, so they have no overloads
        # to read here: a second run of the suite sees only the kernels Python calls directly.
        pytest.skip(f"{loaded} kernels came from Numba's cache; run with an empty cache to check their callees")
    assert checked > 20


#: The heavy callees that every path shares: each compiles once per dtype only if every caller passes
#: the same types (no constant that Numba types as a literal, no read-only or 'A' layout arrays).
SHARED_CALLEES = {
    ("distance", "pair_distance"),
    ("distance", "pair_distance_any_room"),
    ("gjk3d", "_triangle"),
    ("motion", "pair_time_of_impact"),
}


def test_shared_callees_compile_once_per_dtype():
    # A literal argument (True, 0) or the one-pair kernels' read-only 'A' poses reaching a shared callee
    # compiles it once more (pair_distance: 20-30 s of a cold start on 2 cores).
    found, loaded = _call_every_path()
    sigs = {(mod, name): [str(s) for s in obj.signatures if "float32" not in str(s)] for mod, name, obj in found}
    missing = sorted(k for k in SHARED_CALLEES if not sigs.get(k))
    if missing and loaded:
        # Numba's cache keeps no callee signatures: a callee compiled into a cached kernel shows none.
        pytest.skip(f"{loaded} kernels came from Numba's cache; run with an empty cache to see {missing}")
    assert not missing
    for key in SHARED_CALLEES:
        assert len(sigs[key]) == 1, f"{key} compiled for {len(sigs[key])} float64 signatures: {sigs[key]}"
        for bad in ("Literal", "'A'", "True, aligned"):  # (a read-only array prints as "..., True, aligned=True)")
            assert bad not in sigs[key][0], f"{key}: {sigs[key][0]}"


def test_the_pair_bundle_holds_both_prisms_and_the_scalars():
    # The one-pair kernels take both packed prisms and their scalars as one int64 array (pair_bundle):
    # the compiled unbundle (what they read) and unbundle.py_func give back exactly what went in.
    import numpy as np

    import prismbatch as pb
    from prismbatch._kernels.one_pair import pair_bundle, unbundle

    for dt in (np.float64, np.float32):
        for na, nb in ((5, 3), (4, 40), (3, 7)):  # odd and even counts of float32 words
            a = pb.PrismSet([pb.Prism.regular(na, 1.0)]).kernel_arrays(dt)
            b = pb.PrismSet([pb.Prism.regular(nb, 2.5)]).kernel_arrays(dt)
            scalars = (1e-9, 0.5, 2.0**-52, 1e-6, 3e-7, 1e15)
            bundle = pair_bundle(a, b, *scalars)
            like = np.zeros(3, dtype=dt)
            for parts in (unbundle(bundle, like), unbundle.py_func(bundle, like)):
                want = (a.floats, a.ints, b.floats, b.ints)
                for got, w in zip(parts[:4], want):
                    assert got.dtype == w.dtype and np.array_equal(got, w)
                assert parts[4].dtype == np.float64 and parts[4].tolist() == list(scalars)
