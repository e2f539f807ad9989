"""Stability of periodic solutions by Hill's method (Floquet exponents from the HBM Jacobian).

A perturbation e^{s t} v(omega t) of a periodic solution, with v expanded on the same harmonics,
satisfies the quadratic eigenvalue problem

    (J + s Delta1 + s^2 Delta2) v = 0,

J the HBM Jacobian at the solution (with the AFT's contact Jacobian: the contact law linearised
about the steady period, the usual approximation for hysteretic elements) and Delta1, Delta2 from
the problem (Problem.hill_operators).  It is solved in the first-order form
[[0, I], [-J, -Delta1]] z = s [[I, 0], [0, Delta2]] z (dense; massless coordinates give infinite
eigenvalues, which are dropped).  Every Floquet exponent appears 2H+1 times, shifted by i k omega;
of the finite eigenvalues the ``Problem.num_dynamic()`` with the smallest |Im s| are taken
(Lazarus and Thomas 2010; NLvib and tmdsimpy select the same way).  The solution is stable when
the largest real part is below ``tol`` omega: a fold puts a real exponent through zero.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from ..hbm.problem import Evaluation, Problem

STABILITY_RTOL = 1e-7  # stable when max Re s <= STABILITY_RTOL * omega (Hill's truncation and round-off)


def floquet_exponents(J, d1, d2, num: int) -> np.ndarray:
    """The ``num`` Floquet exponents (1/s) of Hill's problem (J + s d1 + s^2 d2) v = 0.

    Unknowns on which neither d1 nor d2 acts (the penalty ROM's internal variables, which carry
    neither mass nor damping) only give infinite eigenvalues: they are condensed out statically
    first (Schur complement of J), which leaves the same finite exponents.  With the remaining d2
    invertible the first-order form is a standard eigenproblem, else a generalised one."""
    J, d1, d2 = (np.asarray(a.toarray() if sp.issparse(a) else a, dtype=float) for a in (J, d1, d2))
    static = ~((d1 != 0).any(axis=0) | (d1 != 0).any(axis=1) | (d2 != 0).any(axis=0) | (d2 != 0).any(axis=1))
    if static.any():
        d, st = np.flatnonzero(~static), np.flatnonzero(static)
        J = J[np.ix_(d, d)] - J[np.ix_(d, st)] @ np.linalg.solve(J[np.ix_(st, st)], J[np.ix_(st, d)])
        d1, d2 = d1[np.ix_(d, d)], d2[np.ix_(d, d)]
    n = J.shape[0]
    I, Z = np.eye(n), np.zeros((n, n))
    try:  # d2 = I (x) M: symmetric, and positive definite once the static unknowns are out
        c = sla.cho_factor(d2)
        s = np.linalg.eigvals(np.block([[Z, I], [-sla.cho_solve(c, J), -sla.cho_solve(c, d1)]]))
    except np.linalg.LinAlgError:  # a massless but damped coordinate: the generalised problem
        s = sla.eigvals(np.block([[Z, I], [-J, -d1]]), np.block([[I, Z], [Z, d2]]))
    s = s[np.isfinite(s)]
    return s[np.argsort(np.abs(s.imag), kind="stable")][:num]


def max_real_part(problem: Problem, lam: float, evaluation: Evaluation) -> float | None:
    """The largest real part of the point's Floquet exponents (1/s), or None where the problem
    offers no Hill operators or says why its exponents are not the physical ones."""
    if problem.no_stability is not None:
        return None
    ops = problem.hill_operators(lam)
    if ops is None or evaluation.J is None:
        return None
    s = floquet_exponents(evaluation.J, ops[0], ops[1], problem.num_dynamic())
    return float(s.real.max())


def is_stable(max_real: float, omega: float) -> bool:
    return max_real <= STABILITY_RTOL * abs(omega)
