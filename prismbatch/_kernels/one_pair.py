"""One pair from Python: the pair bundle, the pose checks and ``collide_pair``, the low-latency path.

``Collider.collide_pair`` and ``Collider.distance`` on one pair call one compiled function each, with the
prism tables and scalars packed into one array (:func:`pair_bundle`) and the poses checked in the kernel
(:func:`pair_problem`); each is compiled for one signature and closed to others (:func:`close_kernel`).
"""

import numba
import numpy as np

from .batch import pair_of_sets, unpack
from .checks import rotation_problem
from .jit import first_call, jit, per_dtype

#: Problem code of :data:`collide_pair` for a pose array of the wrong length (the caller converts and says which).
PAIR_SHAPE_PROBLEM = 9


@jit(inline="always")
def pair_problem(Pa, Ra, Pb, Rb, ortho_tol_a, ortho_tol_b, max_magnitude):
    """(problem, value) of one pair's poses, checked in the kernel: 0 if valid, else the first bad
    input (1-4 for a, 5-8 for b, :data:`PAIR_SHAPE_PROBLEM`; see pair.pair_problem_message)."""
    # Shapes are checked here, not by the caller: a (2,) position would be read out of bounds.
    if Pa.shape[0] != 3 or Pb.shape[0] != 3 or Ra.shape != (3, 3) or Rb.shape != (3, 3):
        return PAIR_SHAPE_PROBLEM, 0.0
    # a's position, a's rotation, then b's: the order in which the batch's pose parser names them
    for k, (P, R, ortho_tol) in enumerate(((Pa, Ra, ortho_tol_a), (Pb, Rb, ortho_tol_b))):
        for j in range(3):
            if not abs(P[j]) <= max_magnitude:  # also NaN
                return 1 + 4 * k, np.float64(P[j])
        kind, val = rotation_problem(R, ortho_tol)  # (R may be a strided view: no reshape)
        if kind != 0:
            return 1 + kind + 4 * k, np.float64(val)
    return 0, 0.0


#: A pair bundle's header: the lengths of a's and b's int arrays, the length of a's floats, the start and
#: length of b's floats (in elements of the float dtype); then the six scalars of :func:`pair_scalars`.
BUNDLE_HEAD, BUNDLE_SCALARS = 5, 6


def pair_bundle(a_arrays, b_arrays, rtol, atol, eps, ortho_tol_a, ortho_tol_b, max_magnitude):
    """Everything a one-pair kernel takes besides the poses, as one int64 array (see :func:`unbundle`).

    Each array crosses the dispatcher at some 75 ns a call: the two packed prisms (four arrays) and the
    scalars cost a one-pair query 0.3 µs as five arguments. The floats keep their dtype, stored as raw
    words: b's start on a word, so that both are views of one reinterpretation.
    """
    fa, fb = a_arrays.floats, b_arrays.floats
    per_word = 8 // fa.itemsize
    start_b = -(-fa.size // per_word) * per_word
    floats = np.zeros(-(-(start_b + fb.size) // per_word) * per_word, dtype=fa.dtype)
    floats[: fa.size] = fa
    floats[start_b : start_b + fb.size] = fb
    head = np.array([a_arrays.ints.size, b_arrays.ints.size, fa.size, start_b, fb.size], dtype=np.int64)
    scalars = np.array([rtol, atol, eps, ortho_tol_a, ortho_tol_b, max_magnitude], dtype=np.float64)
    return np.concatenate((head, scalars.view(np.int64), a_arrays.ints, b_arrays.ints, floats.view(np.int64)))


@jit(inline="always", refcounts=True)  # returns arrays (when called from Python, not inlined)
def unbundle(bundle, like):
    """``(a_floats, a_ints, b_floats, b_ints, scalars)`` of a :func:`pair_bundle`, as views; ``like``: an
    array of the floats' dtype (a pose). Python takes them apart with ``unbundle.py_func``; a test compares."""
    ka, kb, fa, start_b, fb = bundle[0], bundle[1], bundle[2], bundle[3], bundle[4]
    s = BUNDLE_HEAD + BUNDLE_SCALARS
    floats = bundle[s + ka + kb :].view(like.dtype)
    return (
        floats[:fa],
        bundle[s : s + ka],
        floats[start_b : start_b + fb],
        bundle[s + ka : s + ka + kb],
        bundle[BUNDLE_HEAD:s].view(np.float64),
    )


@jit(inline="always")
def pair_scalars(scalars):
    """``(rtol, atol, eps, ortho_tol_a, ortho_tol_b, max_magnitude)``: the scalars of a :func:`pair_bundle`."""
    return scalars[0], scalars[1], scalars[2], scalars[3], scalars[4], scalars[5]


def _collide_pair(bundle, Pa, Ra, Pb, Rb, contact):
    """One pair, with its input checks compiled in (the low-latency path).

    ``bundle``: :func:`pair_bundle`. Returns one int, ``2 * case + hit``, and writes the contact
    point (NaN if no hit) into ``contact``, a float64 (3,) array: the caller's ``np.empty(3)``
    costs a third of building the array from three returned floats, and one returned int costs
    less than a tuple. A negative return is minus a problem code (the first bad input, see
    :func:`pair_problem`); the offending number is then ``contact[0]``.
    """
    a_floats, a_ints, b_floats, b_ints, scalars = unbundle(bundle, Pa)
    rtol, atol, eps, ortho_tol_a, ortho_tol_b, max_magnitude = pair_scalars(scalars)
    problem, val = pair_problem(Pa, Ra, Pb, Rb, ortho_tol_a, ortho_tol_b, max_magnitude)
    if problem:
        contact[0] = val
        return -problem
    a, b = unpack(a_floats, a_ints), unpack(b_floats, b_ints)
    # (np.bool_: a literal True would compile pair_test and its callees once more, for that constant)
    hit, case, cx, cy, cz = pair_of_sets(a, b, 0, 0, Pa, Ra, None, Pb, Rb, rtol, atol, eps, np.bool_(True), None)
    contact[0], contact[1], contact[2] = cx, cy, cz
    return 2 * case + hit


#: The one-pair kernel, one compiled copy per dtype. Each is compiled for one signature
#: (:func:`pair_signature`) and closed to others (``disable_compile``), so that a call with anything
#: else (another dtype, a read-only array, a list) raises TypeError instead of compiling a
#: specialisation: ``Collider.collide_pair`` then converts the arguments and calls again.
collide_pair = per_dtype(_collide_pair, "collide_pair", (np.float64, np.float32), error_model="numpy")


def pair_signature(dtype, last):
    """The one signature of a one-pair kernel of ``dtype`` (``collide_pair``, ``distance_pair``): the
    bundle, the poses in any layout and read-only, so that views (a 4x4 transform's ``T[:3, 3]`` and
    ``T[:3, :3]``), frozen and ``np.broadcast_to`` arrays pass as they are (writeable ones convert; a call
    that Numba's dispatcher refuses costs some 0.1 ms in its TypeError, a hundred one-pair queries), then
    the Numba type ``last`` of its last argument."""
    f = numba.from_dtype(np.dtype(dtype))
    vector = numba.types.Array(f, 1, "A", readonly=True)
    matrix = numba.types.Array(f, 2, "A", readonly=True)
    return (numba.types.Array(numba.types.int64, 1, "C"), vector, matrix, vector, matrix, last)


#: The Numba type of ``collide_pair``'s last argument, the contact's float64 (3,) array.
CONTACT_TYPE = numba.types.Array(numba.types.float64, 1, "C")


def close_kernel(kernel, signature):
    """Compile (or load from the cache) ``kernel`` for ``signature`` alone and close it to others."""
    first_call(kernel, kernel.compile, signature)
    kernel.disable_compile()
