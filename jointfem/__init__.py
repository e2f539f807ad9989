"""jointfem: nonlinear vibration of jointed structures by harmonic balance with node-to-node
contact (Jenkins and other laws), penalty and CMS reduced-order models, and FEniCSx continua.

The layout (docs/theory.md, "Layout"): scene -> model -> reduced model -> problem -> analysis ->
results -> plots.  ``jointfem.app`` is the library layer the command line and the demos call.
"""
from .scene import Scene, SceneError, create_structure, load_scene  # noqa: F401

__version__ = "0.1.0"


def compute_frf(model, options, **kw):
    """See jointfem.analysis.frf.compute_frf (imported lazily: `import jointfem` stays light)."""
    from .analysis.frf import compute_frf as _compute

    return _compute(model, options, **kw)
