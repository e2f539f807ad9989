"""External models (``kind = "matrices"``): K, M and D from files, contact pairs as DOF pairs.

This is how a reduction exported from Abaqus, Ansys or Nastran (or any code) comes in: the
matrices are read from MatrixMarket (``.mtx``), NumPy (``.npy``, or ``.npz`` written by
scipy.sparse.save_npz) or MATLAB (``.mat``, the variable named in the scene) files.  DOFs are named
``0, 1, ...`` unless the scene names them.  A Jenkins pair joins DOFs (or a DOF and ground) along
one or two tangential directions and optionally a normal one, each given as ``[a, b]``:
g = u_a - u_b.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.io as sio
import scipy.sparse as sp

from .lumped import force_vectors, jenkins_groups
from .structure import Structure


class MatrixFileError(ValueError):
    """A matrix file that cannot be read or does not fit (the scene layer names the key)."""


@dataclass(frozen=True)
class DofPairSpec:
    tangential: tuple[tuple[str, str], ...]  # 1 or 2 [a, b] DOF pairs (b may be ground)
    normal: tuple[str, str] | None
    kt: float
    kn: float
    mu: float
    N0: float


@dataclass(frozen=True)
class MatricesSpec:
    K: sp.csr_matrix
    M: sp.csr_matrix
    D: sp.csr_matrix
    dof_names: tuple[str, ...]
    jenkins: tuple[DofPairSpec, ...]
    forces: tuple  # of lumped.ForceSpec (dof names)
    outputs: tuple[str, ...]


def read_matrix(path: Path, variable: str | None = None) -> sp.csr_matrix:
    """A square real matrix from .mtx, .npy, .npz (scipy.sparse.save_npz) or .mat (``variable``)."""
    path = Path(path)
    try:
        if path.suffix == ".mtx":
            A = sio.mmread(str(path))
        elif path.suffix == ".npy":
            A = np.load(path, allow_pickle=False)
        elif path.suffix == ".npz":
            A = sp.load_npz(path)
        elif path.suffix == ".mat":
            data = sio.loadmat(str(path))
            names = [k for k in data if not k.startswith("__")]
            if variable is None and len(names) == 1:
                variable = names[0]
            if variable not in data:
                raise MatrixFileError(f"no variable {variable!r} in it (it holds {', '.join(names)})")
            A = data[variable]
        else:
            raise MatrixFileError("must end in .mtx, .npy, .npz or .mat")
    except (OSError, ValueError) as exc:
        if isinstance(exc, MatrixFileError):
            raise
        raise MatrixFileError(f"cannot be read: {exc}") from None
    A = sp.csr_matrix(A, dtype=float)
    if A.shape[0] != A.shape[1]:
        raise MatrixFileError(f"is {A.shape[0]} x {A.shape[1]}, not square")
    if not np.all(np.isfinite(A.data)):
        raise MatrixFileError("holds a non-finite value")
    return A


def create_matrices(spec: MatricesSpec) -> Structure:
    names = spec.dof_names
    index = {nm: i for i, nm in enumerate(names)}
    n = len(names)
    fc, fs, f0 = force_vectors(spec.forces, index, n)
    comps = [list(j.tangential) + ([j.normal] if j.normal is not None else []) for j in spec.jenkins]
    contacts = jenkins_groups(list(spec.jenkins), comps, [f"{j.tangential[0][0]}-{j.tangential[0][1]}"
                                                          for j in spec.jenkins], index, n)
    return Structure(K=spec.K, M=spec.M, D=spec.D, fc=fc, fs=fs, contacts=tuple(contacts), dof_names=names,
                     outputs={nm: index[nm] for nm in spec.outputs}, info={"kind": "matrices"},
                     f0=f0 if np.any(f0) else None)
