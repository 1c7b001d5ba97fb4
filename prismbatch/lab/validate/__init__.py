"""Monte Carlo validation at scale: prismbatch against python-fcl and an exact LP.

:func:`validate` runs it, :func:`format_validation` and :func:`write_validation` report it;
:func:`generate_block` regenerates any block of a run from its seed. The method (seeding,
touching band, stand-ins, contact check) is described in ``docs/methods/validation.md``.

Modules: ``config`` (settings, constants, seeding), ``generate`` (shapes and poses),
``blocks`` (one block: prismbatch, FCL, the LP), ``arbitrate`` (who is wrong), ``merge``
(counters, :class:`ValidationResult`), ``distance`` (the signed-distance section, against
:mod:`prismbatch.lab.distance_ref` and coal), ``driver`` (:func:`validate`), ``output`` (reports).
"""

from .blocks import residuals as residuals
from .blocks import run_chunk, set_numba_threads, warm
from .config import BLOCK_SIZE, DISTRIBUTION_NAMES, LP_REL, RECORD_KINDS, SHAPE_KINDS, make_config
from .config import DEGENERATE_CASES as DEGENERATE_CASES
from .driver import validate
from .generate import Block as Block
from .generate import generate_block
from .generate import make_shape as make_shape
from .merge import ValidationResult
from .output import CASES_HEADER as CASES_HEADER
from .output import SUMMARY_HEADER as SUMMARY_HEADER
from .output import format_validation, write_validation

# Also importable from here, outside __all__: Block, DEGENERATE_CASES, SUMMARY_HEADER and
# CASES_HEADER (as before the split); make_shape and residuals (internal, for the tests).
__all__ = [
    "validate",
    "ValidationResult",
    "format_validation",
    "write_validation",
    "run_chunk",
    "generate_block",
    "make_config",
    "warm",
    "set_numba_threads",
    "BLOCK_SIZE",
    "DISTRIBUTION_NAMES",
    "SHAPE_KINDS",
    "RECORD_KINDS",
    "LP_REL",
]
