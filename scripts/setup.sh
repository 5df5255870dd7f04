#!/bin/sh
# Set up impact_fenics on Debian bookworm: system FEniCSx packages (only if
# missing), a venv that sees them, and the package installed editable into it.
# Idempotent: a second run takes seconds.
set -eu
cd "$(dirname "$0")/.."

PACKAGES="python3-dolfinx python3-petsc4py python3-mpi4py python3-ufl python3-basix \
python3-gmsh openmpi-bin python3-scipy python3-matplotlib python3-pytest python3-venv \
python3-slepc4py gcc libgl1 libegl1 libx11-6 libxrender1 python3-h5py python3-setuptools \
python3-wheel libopenblas0-serial"
VENV="${VENV:-.venv}"

missing=""
for p in $PACKAGES; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing="$missing $p"
done
if [ -n "$missing" ]; then
    echo "setup: installing Debian packages:$missing"
    if [ "$(id -u)" -eq 0 ]; then SUDO=""; elif command -v sudo >/dev/null; then SUDO="sudo"; else
        echo "error: missing Debian packages ($missing) and no root or sudo to install them" >&2
        exit 1
    fi
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq $missing >/dev/null
fi

if [ ! -x "$VENV/bin/python" ]; then
    echo "setup: creating $VENV (system site packages visible)"
    /usr/bin/python3 -m venv --system-site-packages "$VENV"
fi

# reinstall only when the package metadata changed
stamp="$VENV/.impact_fenics.stamp"
want="$(cat pyproject.toml | md5sum | cut -d' ' -f1)"
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
    echo "setup: installing impact_fenics (editable) and its PyPI extras into $VENV"
    "$VENV/bin/python" -m pip install -q --disable-pip-version-check --no-build-isolation -e ".[plot]"
    echo "$want" > "$stamp"
fi
"$VENV/bin/python" -c "import dolfinx, impact_fenics" || {
    echo "error: the venv cannot import dolfinx and impact_fenics" >&2; exit 1; }
