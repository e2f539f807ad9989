"""Shared systems and references of the test files.

Plain helpers, imported as ``from conftest import ROOT, sdof``: pytest's default ("prepend")
import mode puts this directory on sys.path before it imports this file as the module
``conftest`` (tests/ has no __init__.py), the same way the tests find reference_timeint.py.
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from jointfem.models.lumped import ForceSpec, JenkinsSpec, LinkSpec, LumpedSpec, MassSpec

# JOINTFEM_TEST_PERTURB_K=SEED (tools/test_portability.sh): every structure a scene builds has K's
# entries changed at random by up to 1e-15 of themselves, symmetrically, as round-off on another
# machine would change them (issue 51).  Off by default.
if os.environ.get("JOINTFEM_TEST_PERTURB_K"):
    import dataclasses

    import jointfem.scene as _scene

    _build = _scene._create_structure

    def _perturbed(scene, _seed=int(os.environ["JOINTFEM_TEST_PERTURB_K"])):
        s = _build(scene)
        K = s.K.tocsr()
        E = K.copy()
        E.data = E.data * np.random.default_rng(_seed).uniform(-1e-15, 1e-15, E.data.size)
        return dataclasses.replace(s, K=(K + 0.5 * (E + E.T)).tocsr())

    _scene._create_structure = _perturbed

ROOT = Path(__file__).resolve().parents[1]  # the repository: demos/ and the scenes are under it

# `make test-fast` (pytest -m "not slow"): every test whose recorded duration (tests/durations.json,
# tools/record_durations.py from a whole-suite run) is above SLOW_S seconds is marked slow, beside
# the tests marked by hand.  A test not in the record counts as fast until the record is redone.
SLOW_S = 2.5


def pytest_collection_modifyitems(config, items):
    import json

    import pytest

    record = Path(__file__).with_name("durations.json")
    durations = json.loads(record.read_text()) if record.is_file() else {}
    for item in items:
        if durations.get(item.nodeid, 0.0) > SLOW_S:
            item.add_marker(pytest.mark.slow)
    if getattr(config.option, "numprocesses", None):
        # on pytest-xdist workers (make test): the longest tests first, so that no worker is left
        # running a long one alone at the end (it was: demos/paper_figures.py's 2.5 min, on one of
        # two workers, after the other had finished); the order is the same on every worker
        items.sort(key=lambda it: -durations.get(it.nodeid, 0.0))


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
