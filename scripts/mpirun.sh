#!/bin/sh
# mpirun for this project, for either stack:
# - MPIEXEC if set;
# - else the mpiexec beside the program to run (found on PATH if given without a
#   path), when MPICH's is there: a venv with the MPICH wheel, e.g.
#   .venv-modern/bin/python -> .venv-modern/bin/mpiexec;
# - else the system's OpenMPI mpirun (Debian's stack), with --oversubscribe, and the
#   two variables OpenMPI needs to run as root, set only when root.
# Usage as mpirun: scripts/mpirun.sh -n 2 PROGRAM ARGS...
if [ -z "${MPIEXEC:-}" ]; then
    prev=""
    for a in "$@"; do
        case "$prev" in -n|-np) prev=""; continue ;; esac
        case "$a" in
            -*) prev="$a"; continue ;;
        esac
        prog="$(command -v "$a" 2>/dev/null || true)"
        dir="$(dirname "${prog:-.}")"
        if [ -n "$prog" ] && [ -x "$dir/mpiexec" ] && [ -x "$dir/mpichversion" ]; then
            MPIEXEC="$dir/mpiexec"
        fi
        break  # the program: the first argument that is not an option
    done
fi
if [ -n "${MPIEXEC:-}" ]; then
    exec "$MPIEXEC" "$@"
fi
if [ "$(id -u)" -eq 0 ]; then
    export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
fi
exec mpirun --oversubscribe "$@"
