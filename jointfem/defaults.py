"""Defaults that more than one module needs, defined once (no jointfem imports: the bottom layer)."""

ROM_MODES = 20  # vibration modes of a ROM (--modes)
ROM_TVD = 0  # trial-vector derivatives of a ROM (--tvd)
COMPARE_METHODS = "cb,rubin,macneal,dcb,cc,tvd:20:3,penalty"  # jointfem compare's --methods


def default_samples(harmonics: int) -> int:
    """AFT time samples N for H harmonics when a scene gives none: at least 256, and 4H + 4 so
    that the sampled law resolves the retained harmonics well beyond the Nyquist bound 2H + 1."""
    return max(256, 4 * harmonics + 4)
