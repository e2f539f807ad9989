"""How far a point is from harmonic convergence: an estimate of the truncation error per point.

The contact forces are the only source of higher harmonics.  Their content in the two highest
retained harmonics, relative to all their dynamic (k >= 1) content,

    e = sqrt(sum_{k = H-1, H} |F_k|^2) / sqrt(sum_{k = 1..H} |F_k|^2)   (every pair and component),

is what a truncation at H throws away the next part of: where it is small, the harmonics beyond H
carry less still (they decay at least as fast for the laws here: a kink in the force's slope
gives 1/k^2, a jump 1/k).  A linear (stuck) contact has e = 0.  Two top harmonics, because a
symmetric law (the Jenkins pair without a normal axis) has no even ones: one of the two is odd.
For H <= 2 the top would include the fundamental, and e = 1: not known to be converged (at H = 2
the second harmonic alone reads 6e-19 on the slipping SDOF oscillator, whose third is 0.14).
"""
from __future__ import annotations

import numpy as np

from ..contact.law import ContactResult
from ..harmonics import Harmonics


def top_harmonic_share(contact: list[ContactResult], harmonics: Harmonics, *, top: int = 2) -> float:
    """e of the module docstring for the contact results of one point (0 without contact)."""
    if not contact or harmonics.H < 1:
        return 0.0
    F = np.concatenate([c.F.reshape(harmonics.num_hc, -1) for c in contact], axis=1)  # (num_hc, all comps)
    orders = harmonics.orders
    dyn = float(np.sum(F[orders >= 1] ** 2))
    if dyn <= 0.0:
        return 0.0
    if harmonics.H <= top:
        return 1.0  # the top harmonics would include the fundamental: not known to be converged
    hi = float(np.sum(F[orders > harmonics.H - top] ** 2))
    return float(np.sqrt(hi / dyn))
