"""Shared systems and references of the test files.

Plain helpers, imported as ``from conftest import ROOT, sdof``: pytest's default ("prepend")
import mode puts this directory on sys.path before it imports this file as the module
``conftest`` (tests/ has no __init__.py), the same way the tests find reference_timeint.py.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from jointfem.models.lumped import ForceSpec, JenkinsSpec, LinkSpec, LumpedSpec, MassSpec

ROOT = Path(__file__).resolve().parents[1]  # the repository: demos/ and the scenes are under it


def sdof(F, *, c=0.02, N0=1.0):
    """The SDOF Jenkins oscillator: m = k = kt = mu = 1, one slider to ground with slip force
    Fs = mu N0 (1 by default), viscous damping c (no damper at all when c = 0), forcing F cos(w t)."""
    return LumpedSpec(
        masses=(MassSpec("m", 1.0),), springs=(LinkSpec("m.x", "ground", 1.0),),
        dampers=(LinkSpec("m.x", "ground", c),) if c else (),
        jenkins=(JenkinsSpec("m", "ground", ("x",), None, kt=1.0, kn=0.0, mu=1.0, N0=N0),),
        forces=(ForceSpec("m.x", F),), outputs=("m.x",))


def linear_amplitude(omega, k, F, *, c=0.02, m=1.0):
    """Closed-form amplitude of the linear oscillator m x'' + c x' + k x = F cos(w t):
    F / |k - m w^2 + i c w|."""
    return F / np.abs(k - m * omega**2 + 1j * c * omega)
