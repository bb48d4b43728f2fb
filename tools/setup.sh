#!/usr/bin/env bash
# Install what crosshead needs on Debian 12, skipping whatever is already there.
#   Debian: python3-dolfinx (0.5.2, PETSc with MUMPS/hypre), python3-gmsh, python3-meshio, python3-matplotlib,
#           an optimised BLAS (MUMPS is ~5x slower on the reference BLAS), calculix-ccx (bench).
#   .venv:  made from /usr/bin/python3 with --system-site-packages; pyvista, pytest, ruff, ...
#           from PyPI, constrained to Debian's numpy (numpy 2 breaks Debian's petsc4py);
#           the crosshead command (pyproject.toml), installed editable.
set -euo pipefail
cd "$(dirname "$0")/.."

APT_PKGS="python3-dolfinx python3-gmsh python3-meshio python3-markdown python3-matplotlib python3-venv python3-pip libopenblas0-pthread calculix-ccx mpi-default-bin"
missing=""
for p in $APT_PKGS; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing="$missing $p"
done
if [ -n "$missing" ]; then
  echo "setup: installing Debian packages:$missing"
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq $missing >/dev/null
fi

stamp=.venv/.setup-done
want="$(cat requirements.txt constraints.txt pyproject.toml | sha1sum | cut -c1-40)"
if [ ! -x .venv/bin/python ] || [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
  echo "setup: creating .venv (system site packages + PyPI requirements)"
  [ -x .venv/bin/python ] || /usr/bin/python3 -m venv --system-site-packages .venv
  # One matplotlib: Debian's. A PyPI copy left in the .venv by an earlier set-up shadows it
  # but not its mpl_toolkits (constraints.txt says why), so it goes before pip looks.
  if [ -n "$(.venv/bin/python -c 'import matplotlib, sys; print(matplotlib.__file__) if matplotlib.__file__.startswith(sys.prefix) else None' 2>/dev/null | grep -v None)" ]; then
    .venv/bin/pip uninstall -q -y --disable-pip-version-check matplotlib
  fi
  .venv/bin/pip install -q --disable-pip-version-check -c constraints.txt -r requirements.txt
  # The crosshead command (pyproject.toml), editable: it runs this checkout's code.
  .venv/bin/pip install -q --disable-pip-version-check --no-deps --no-build-isolation -e .
  .venv/bin/python -W error::UserWarning -c "import dolfinx, gmsh, petsc4py, pyvista, numpy, mpl_toolkits.mplot3d; assert numpy.__version__.startswith('1.'), numpy.__version__" \
    || { echo "setup: the venv cannot import dolfinx/pyvista/matplotlib with Debian's numpy" >&2; exit 1; }
  # The forms of the default path compile here, once, not one by one before the first
  # answer (the cache is .venv/cache/fenics, see pipeline/runtime/environment.py).
  echo "setup: compiling the finite-element forms (once, about a minute)"
  warm=$(mktemp -d)
  .venv/bin/crosshead run --size 05 --mesh-factor 4 --levels 3 --quiet --out "$warm/run" >/dev/null
  rm -rf "$warm"
  echo "$want" > "$stamp"
fi
