"""jointfem: nonlinear vibration of jointed structures by harmonic balance with node-to-node
Jenkins contact (full order now; penalty ROMs and FEniCSx continua to come)."""
from .scene import Scene, SceneError, create_structure, load_scene  # noqa: F401

__version__ = "0.1.0"


def compute_frf(structure, options, **kw):
    """See jointfem.frf.compute_frf (imported lazily)."""
    from .frf import compute_frf as _compute

    return _compute(structure, options, **kw)
