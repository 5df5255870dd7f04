#!/bin/sh
# Run pytest on N ranks (default 2). Rank 0 reports; other ranks log to a file
# that is printed when they fail. A failing rank aborts all (tests/conftest.py),
# and the whole run sits under a timeout so that nothing can hang.
# PY picks the stack: .venv/bin/python (Debian, OpenMPI's mpirun) or
# .venv-modern/bin/python (the wheels, MPICH's mpiexec beside it).
set -u
cd "$(dirname "$0")/.."
N="${N:-2}"
PY="${PY:-.venv/bin/python}"
LOGDIR="$(mktemp -d)"
if [ -z "${MPIEXEC:-}" ] && [ -x "$(dirname "$PY")/mpiexec" ] && [ -x "$(dirname "$PY")/mpichversion" ]; then
    export MPIEXEC="$(dirname "$PY")/mpiexec"
fi
# the rank: OpenMPI sets OMPI_COMM_WORLD_RANK, MPICH's Hydra PMI_RANK
timeout "${MPI_TEST_TIMEOUT:-1500}" scripts/mpirun.sh -n "$N" sh -c '
    rank="${OMPI_COMM_WORLD_RANK:-${PMI_RANK:-0}}"
    if [ "$rank" = 0 ]; then
        exec "$0" -m pytest "$@"
    else
        exec "$0" -m pytest "$@" > "'"$LOGDIR"'/rank${rank}.log" 2>&1
    fi' "$PY" "$@"
rc=$?
if [ $rc -ne 0 ]; then
    for f in "$LOGDIR"/rank*.log; do
        [ -f "$f" ] && { echo "== $f (tail) =="; tail -n 40 "$f"; }
    done
    [ $rc -eq 124 ] && echo "error: the MPI test run timed out" >&2
fi
rm -rf "$LOGDIR"
exit $rc
