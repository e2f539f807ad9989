"""The reductors by name: ``build_rom(structure, method, options)`` returns the reduced model."""
from __future__ import annotations

import time

from ..models.structure import Structure
from . import cms, penalty
from .common import ExactModel, Reduction, RomError, RomOptions

# name -> reductor(structure, options) -> Reduction
REDUCTORS = {
    "exact": lambda structure, options: ExactModel(structure),  # the exact condensation (hbm.condensed)
    "cb": cms.craig_bampton, "rubin": cms.rubin, "macneal": cms.macneal, "dcb": cms.dual_craig_bampton,
    "cc": cms.characteristic_constraint_modes, "tvd": cms.tvd_method, "penalty": penalty.PenaltyROM,
}
METHODS = ("full", *REDUCTORS)  # "full": no reduction
MODAL = ("penalty", "tvd")  # the reductors whose basis starts from the stuck structure's modes
SUBSTRUCTURED = ("cb", "rubin", "macneal", "dcb", "cc")  # the reductors of each substructure (rom.cms)


def build_rom(structure: Structure, method: str, options: RomOptions = RomOptions()) -> Reduction:
    """Build the ROM of ``method`` (one of METHODS but 'full').  Records the offline seconds."""
    check_options(method, options)
    t0 = time.perf_counter()
    rom = REDUCTORS[method](structure, options)
    rom.offline_s = time.perf_counter() - t0
    return rom


def check_options(method: str, options: RomOptions) -> None:
    """Refuse, before any work, a method or a count of modes and TVDs it cannot take."""
    if method not in REDUCTORS:
        raise RomError(f"unknown reduction method {method!r}; choose one of {', '.join(METHODS[1:])}")
    if method != "exact" and (options.modes < 0 or options.tvd < 0):
        raise RomError(f"{method}: modes = {options.modes} and tvd = {options.tvd} must be >= 0")
    if method in MODAL and options.modes < 1:
        # (their basis is built on the stuck modes: without one, there is nothing to add the static
        # modes and derivatives to, and the problem would have no unknowns)
        raise RomError(f"{method}: modes = {options.modes}: this method needs at least one vibration mode (--modes >= 1)")
