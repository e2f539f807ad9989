"""jointfem: nonlinear vibration of jointed structures by harmonic balance with node-to-node
contact (Jenkins and other laws), penalty and CMS reduced-order models, and FEniCSx continua.

The layout (docs/theory.md, "Layout"): scene -> model -> reduced model -> problem -> analysis ->
results -> plots.  ``jointfem.app`` is the library layer the command line and the demos call.
"""
from .scene import Scene, SceneError, create_structure, load_scene  # noqa: F401
from .version import installed_version

__version__ = installed_version()


def compute_frf(model, options, **kw):
    """See jointfem.analysis.frf.compute_frf (imported lazily: `import jointfem` stays light)."""
    from .analysis.frf import compute_frf as _compute

    return _compute(model, options, **kw)


def solve_at(model, omega, harmonics, **kw):
    """See jointfem.analysis.frf.solve_at: the periodic response at one omega (rad/s)."""
    from .analysis.frf import solve_at as _solve

    return _solve(model, omega, harmonics, **kw)


def linear_modes(structure, num=10):
    """See jointfem.app.linear_modes: the linear modes with the joint stuck and free."""
    from .app import linear_modes as _modes

    return _modes(structure, num)


def compute_backbone(model, options, **kw):
    """See jointfem.analysis.nma.compute_backbone: a nonlinear mode (EPMC), frequency and damping
    against amplitude."""
    from .analysis.nma import compute_backbone as _backbone

    return _backbone(model, options, **kw)
