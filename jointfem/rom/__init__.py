"""Reduced-order models: reductors (jointfem.rom.reductors) return reduced models (rom.common)
that offer their HBM problem; the CMS family (cms) and the adaptive penalty ROM (penalty)."""
from .common import BasisError, ExactModel, Reduction, ReducedModel, RomError, RomOptions  # noqa: F401
from .reductors import METHODS, REDUCTORS, build_rom  # noqa: F401
