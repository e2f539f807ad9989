#!/usr/bin/env bash
# Idempotent set-up for a fresh Debian 12 (bookworm) or Debian 13 (trixie) machine: the release's
# FEniCSx stack via apt, a .venv that sees the system site-packages, and jointfem installed editable
# with numpy (and everything else compiled against the system) pinned to the system's versions.
set -euo pipefail
cd "$(dirname "$0")/.."

# The release decides the stack: bookworm has dolfinx 0.5.2, PETSc/SLEPc 3.18, numpy 1.24;
# trixie has dolfinx 0.9, PETSc/SLEPc 3.22, numpy 2.2 (jointfem/fem/compat.py and
# jointfem/linalg.py hold the differences). The package names are the same on both.
codename=$(. /etc/os-release 2>/dev/null && echo "${VERSION_CODENAME:-}") || codename=""
case "$codename" in
  bookworm|trixie) ;;
  *) echo "setup: this is '${codename:-an unknown release}' (/etc/os-release VERSION_CODENAME);" \
          "jointfem's set-up supports Debian 12 (bookworm) and Debian 13 (trixie)" >&2
     exit 1 ;;
esac

# libopenblas0-pthread: numpy and scipy pick it up through Debian's BLAS alternative; the
# reference BLAS made the dense algebra of the ROMs 5x slower (a 420x420 solve: 14 ms against 2.9 ms).
# libegl1 libegl-mesa0 libgl1-mesa-dri: the off-screen renderer that pip's VTK wheel loads (EGL on Mesa's
# software rasteriser); without them a picture segfaults (the wheel finds no X, EGL or OSMesa).
# libmumps-dev: dmumps_c.h, which jointfem.mumps reads to call MUMPS directly (PETSc's development
# package brings it already; named so that it is not left to that).
# python3-h5py: meshio's XDMF writer imports it (jointfem export's field_<i>.xdmf, written as inline XML).
APT_PKGS="python3-dolfinx python3-petsc4py python3-slepc4py python3-gmsh python3-scipy python3-mpi4py python3-venv mpi-default-bin libopenblas0-pthread libegl1 libegl-mesa0 libgl1-mesa-dri libmumps-dev python3-h5py"
missing=""
for p in $APT_PKGS; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing="$missing $p"
done
if [ -n "$missing" ]; then
  echo "setup: installing Debian $codename packages:$missing"
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -q
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q $missing
fi

if [ ! -x .venv/bin/python ]; then
  echo "setup: creating .venv (with system site-packages)"
  /usr/bin/python3 -m venv --system-site-packages .venv
fi

# Pin what the system stack is compiled against, so pip never replaces it.
/usr/bin/python3 - > .venv/constraints.txt <<'PY'
import importlib.metadata as md
for name in ("numpy", "scipy", "mpi4py", "petsc4py", "slepc4py", "fenics-dolfinx"):
    try:
        print(f"{name}=={md.version(name)}")
    except md.PackageNotFoundError:
        pass
PY

stamp=.venv/.jointfem-installed-compat
if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ]; then
  echo "setup: pip install -e .[dev] (constrained to the system numpy)"
  .venv/bin/python -m pip install -q --upgrade "pip>=23" -c .venv/constraints.txt
  # compat mode: a .pth entry for the clone, so that a folder named jointfem in the current
  # directory (a clone's parent folder) cannot shadow the package as an empty namespace package,
  # which the default editable finder (on sys.meta_path after the path finder) lets happen
  .venv/bin/python -m pip install -q -c .venv/constraints.txt -e ".[dev]" --config-settings editable_mode=compat \
    2>/dev/null || .venv/bin/python -m pip install -q -c .venv/constraints.txt -e ".[dev]"
  .venv/bin/python -c "import numpy, petsc4py; from petsc4py import PETSc" \
    || { echo "setup: numpy/petsc4py broken after install" >&2; exit 1; }
  touch "$stamp"
fi
