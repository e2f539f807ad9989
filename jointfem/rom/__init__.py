"""Reduced-order models: the reference CMS family (cms) and the adaptive penalty ROM (penalty)."""
from .common import METHODS, ReducedModel, RomError, RomOptions, build_rom  # noqa: F401
