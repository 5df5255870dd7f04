#!/bin/sh
# Set up impact_fenics on the current FEniCSx (dolfinx 0.11 from PyPI wheels):
# .venv-modern from the first Python >= 3.12 found (PYTHON_MODERN, then PATH,
# then pyenv's versions), the pinned wheel stack of scripts/requirements-modern.txt
# and this package (editable). Idempotent: a second run takes about a second.
set -eu
cd "$(dirname "$0")/.."
VENV="${VENV_MODERN:-.venv-modern}"
REQS=scripts/requirements-modern.txt

is_modern() {  # runs, and is Python >= 3.12
    "$1" -c 'import sys; sys.exit(sys.version_info < (3, 12))' >/dev/null 2>&1
}

find_python() {
    for c in ${PYTHON_MODERN:-} python3 python3.12 python3.13 python3.14; do
        p="$(command -v "$c" 2>/dev/null)" || continue
        is_modern "$p" && { echo "$p"; return 0; }
    done
    for p in $(ls -d "${PYENV_ROOT:-${HOME:-}/.pyenv}"/versions/3.* 2>/dev/null | sort -V); do
        is_modern "$p/bin/python3" && { echo "$p/bin/python3"; return 0; }
    done
    return 1
}

if [ "${1:-}" = "--find-python" ]; then  # only say which Python would be used
    find_python || { echo "error: no Python >= 3.12 on PATH or under pyenv" >&2; exit 1; }
    exit 0
fi

if [ ! -x "$VENV/bin/python" ]; then
    PY="$(find_python)" || {
        echo "error: the modern stack needs Python >= 3.12 (none on PATH or under pyenv; set PYTHON_MODERN)" >&2
        exit 1; }
    echo "setup-modern: creating $VENV from $PY"
    "$PY" -m venv --clear "$VENV"
fi

# reinstall only when the pins or the package metadata changed
stamp="$VENV/.impact_fenics.stamp"
want="$(cat "$REQS" pyproject.toml | md5sum | cut -d' ' -f1)"
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
    echo "setup-modern: installing the pinned FEniCSx 0.11 wheel stack and impact_fenics into $VENV"
    "$VENV/bin/python" -m pip install -q --disable-pip-version-check -r "$REQS"
    "$VENV/bin/python" -m pip install -q --disable-pip-version-check --no-deps \
        --no-build-isolation -e .
    echo "$want" > "$stamp"
fi
"$VENV/bin/python" -c "from mpi4py import MPI; import dolfinx, impact_fenics" || {
    echo "error: $VENV cannot import dolfinx and impact_fenics" >&2; exit 1; }
