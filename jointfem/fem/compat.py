"""Every dolfinx version difference lives here (PETSc/SLEPc ones in jointfem.linalg).

Tested on two stacks (tools/setup.sh installs either):

* Debian 12 (bookworm): dolfinx 0.5.2, ufl 2022.2, gmsh 4.8, PETSc/SLEPc 3.18, numpy 1.24;
* Debian 13 (trixie): dolfinx 0.9.0, ufl 2024.2, gmsh 4.13, PETSc/SLEPc 3.22, numpy 2.2.

The rest of jointfem.fem calls these helpers instead of the version-specific names.  What differs
(each branch below names the version that needs it):

* function spaces: 0.5.2 has ``fem.VectorFunctionSpace(mesh, ("Lagrange", p))`` and
  ``fem.FunctionSpace(mesh, ("Lagrange", p))``; 0.7 onwards has ``fem.functionspace(mesh,
  ("Lagrange", p, (gdim,)))``, ``VectorFunctionSpace`` is gone (0.8) and ``FunctionSpace`` is still
  a class there, but its constructor takes a compiled C++ space, so it must not be called.

The same on both (checked with ``help()`` on each stack):

* ``dolfinx.io.gmshio.model_to_mesh(model, comm, rank, gdim=)`` returns (mesh, cell_tags,
  facet_tags) in 0.5.2 and in 0.9 (0.10 returns a named tuple: not supported here).
* ``fem.form``, ``fem.petsc.assemble_matrix/assemble_vector`` (PETSc Mat/Vec), ``MeshTags.find``,
  ``fem.Constant(mesh, value)`` and its ``value`` setter,
  ``fem.locate_dofs_topological(V, dim, entities)``, ``dofmap.cell_dofs``, index maps'
  ``size_local``/``num_ghosts``/``local_range``/``local_to_global``.
"""
from __future__ import annotations

import contextlib
import logging
import warnings

import numpy as np


def _drop_info(record: logging.LogRecord) -> bool:
    return record.levelno >= logging.WARNING


@contextlib.contextmanager
def quiet_jit():
    """dolfinx 0.5.2 compiles forms through setuptools, which lowers the root logger to INFO and
    logs every compiler call on it: drop those records while compiling.  FFCx's advice on a rule
    of many points (the washers' integrals ask for one on purpose) is dropped too."""
    root = logging.getLogger()
    level = root.level
    root.addFilter(_drop_info)
    try:
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message="Number of integration points per cell")
            yield
    finally:
        root.removeFilter(_drop_info)
        root.setLevel(level)


def import_dolfinx():
    """Import the FEniCSx stack with a clear error when it is missing."""
    try:
        with sigint_kept():  # (dolfinx.io may import gmsh)
            import dolfinx  # noqa: F401
            import dolfinx.fem.petsc  # noqa: F401
            import dolfinx.io  # noqa: F401
            import ufl  # noqa: F401
            from mpi4py import MPI  # noqa: F401
    except ImportError as exc:  # pragma: no cover - depends on the machine
        raise RuntimeError("the continuum models need dolfinx, ufl and mpi4py (Debian: python3-dolfinx; "
                           "run `make setup`)") from exc
    return dolfinx


def model_to_mesh(gmsh_model, comm, gdim: int):
    """Mesh, cell tags and facet tags of the gmsh model built on rank 0."""
    from dolfinx.io import gmshio

    return gmshio.model_to_mesh(gmsh_model, comm, 0, gdim=gdim)


def dolfinx_version() -> tuple[int, int]:
    """(major, minor) of the installed dolfinx."""
    import dolfinx

    major, minor = dolfinx.__version__.split(".")[:2]
    return int(major), int(minor)


def _spaces_from_classes() -> bool:
    """True where function spaces are built by calling the classes ``fem.VectorFunctionSpace`` and
    ``fem.FunctionSpace`` (dolfinx before 0.7: 0.5.2 on bookworm)."""
    return dolfinx_version() < (0, 7)


def vector_space(mesh, degree: int):
    """Lagrange space of ``degree`` with one component per geometric dimension."""
    import dolfinx.fem as fem

    if _spaces_from_classes():  # 0.5.2 (bookworm)
        with quiet_jit():
            return fem.VectorFunctionSpace(mesh, ("Lagrange", degree))
    # 0.7 onwards (0.9 on trixie): the element's value shape is part of the tuple
    return fem.functionspace(mesh, ("Lagrange", degree, (mesh.geometry.dim,)))


def scalar_space(mesh, degree: int):
    """Scalar Lagrange space of ``degree``."""
    import dolfinx.fem as fem

    if _spaces_from_classes():  # 0.5.2 (bookworm)
        with quiet_jit():
            return fem.FunctionSpace(mesh, ("Lagrange", degree))
    # 0.7 onwards (0.9 on trixie): fem.FunctionSpace is a class whose constructor wants a C++ space
    return fem.functionspace(mesh, ("Lagrange", degree))


def owned_blocks(space) -> tuple[np.ndarray, np.ndarray]:
    """Global block indices and coordinates (num_owned, 3) of the blocks (nodes) this rank owns."""
    imap = space.dofmap.index_map
    n = imap.size_local
    return np.arange(imap.local_range[0], imap.local_range[0] + n, dtype=np.int64), \
        space.tabulate_dof_coordinates()[:n]


def vtk_cells(space) -> tuple[np.ndarray, int]:
    """The rank's owned cells as rows of local block indices in VTK's node order, and their VTK
    cell type (one type per mesh).  dolfinx orders a cell's nodes its own way; ``dolfinx.plot``
    permutes them to VTK's, named ``create_vtk_mesh`` in 0.5.2 and ``vtk_mesh`` from 0.7 (0.9 on
    trixie); both return the flat ``[n, i_0 .. i_n-1, n, ...]`` layout over the owned cells."""
    import dolfinx.plot as plot

    make = getattr(plot, "vtk_mesh", None) or plot.create_vtk_mesh
    topology, types, _ = make(space)
    types = np.asarray(types)
    if types.size == 0:
        return np.zeros((0, 0), dtype=np.int32), 0
    if np.any(types != types[0]):
        raise NotImplementedError("meshes of more than one cell type")
    return np.asarray(topology).reshape(types.size, -1)[:, 1:], int(types[0])


def local_to_global(space, local: np.ndarray) -> np.ndarray:
    return np.asarray(space.dofmap.index_map.local_to_global(np.asarray(local, dtype=np.int32)), dtype=np.int64)


def cell_blocks(space, cells: np.ndarray) -> np.ndarray:
    """Local block indices of the given local cells."""
    dm = space.dofmap
    if len(cells) == 0:
        return np.zeros(0, dtype=np.int32)
    return np.unique(np.concatenate([dm.cell_dofs(int(c)) for c in cells]))


def facet_blocks(space, facet_tags, tag: int) -> np.ndarray:
    """Local block indices (owned and ghost) on the facets carrying ``tag``."""
    import dolfinx.fem as fem

    fdim = space.mesh.topology.dim - 1
    return fem.locate_dofs_topological(space, fdim, facet_tags.find(tag))


def constant(mesh, value: float):
    """A real constant of a form, whose ``value`` may be set between assemblies without a new JIT."""
    import dolfinx.fem as fem
    from petsc4py import PETSc

    return fem.Constant(mesh, PETSc.ScalarType(value))


def assemble_matrix(form):
    """Assembled PETSc matrix of a bilinear form (no boundary conditions)."""
    import dolfinx.fem as fem
    import dolfinx.fem.petsc as fp

    with quiet_jit():
        compiled = fem.form(form)
    A = fp.assemble_matrix(compiled)
    A.assemble()
    return A


def assemble_vector(form):
    """Owned part of an assembled linear form, after the ghost contributions are summed."""
    import dolfinx.fem as fem
    import dolfinx.fem.petsc as fp
    from petsc4py import PETSc

    with quiet_jit():
        compiled = fem.form(form)
    b = fp.assemble_vector(compiled)
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    return b.array.copy()


def _sigint_action():
    import signal

    return signal.getsignal(signal.SIGINT)


# SIGINT's action before any library here could change it (this module is imported before gmsh):
# ignored where the process was started so (`nohup`, a non-interactive shell's `cmd &`)
_SIGINT_AT_START = _sigint_action()


@contextlib.contextmanager
def sigint_kept():
    """Around an import or call that may take SIGINT's action (gmsh): SIGINT is blocked meanwhile and
    its action put back (restore_sigint) before it is unblocked, so that a SIGINT arriving in
    between meets the action the process had, not gmsh's default (which kills the process: gmsh's
    import and initialise take 0.4 s).  Only in the main thread, where signals are handled."""
    import signal
    import threading

    main = threading.current_thread() is threading.main_thread()
    before = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT}) if main else None
    try:
        yield
    finally:
        restore_sigint()
        if main:
            signal.pthread_sigmask(signal.SIG_SETMASK, before)


def restore_sigint() -> None:
    """SIGINT's action back after gmsh: gmsh 4.8's module sets SIGINT to SIG_DFL when it is imported
    (later releases in initialize unless interruptible=False), so that Ctrl-C killed the process and
    a sweep lost its converged points (issue 50).  Python's handler (KeyboardInterrupt) is put back,
    or SIG_IGN where the process started with SIGINT ignored (it stays ignored, as the command
    line's policy has it).  Only where gmsh left the default action or a handler of its own (a
    handler someone installed on purpose stays), and only in the main thread."""
    import signal
    import threading

    if threading.current_thread() is threading.main_thread() and _sigint_action() in (signal.SIG_DFL, None):
        signal.signal(signal.SIGINT, signal.SIG_IGN if _SIGINT_AT_START is signal.SIG_IGN
                      else signal.default_int_handler)
