"""What jit_watch says of numba's on-disk cache before anything compiles (cold_share).

The oracle is the file system: a scratch package whose kernels are compiled,
cached, and then edited.
"""
import os
import subprocess
import sys
import textwrap
import time

from conftest import clean_mpi_env  # (under mpirun: the child is not a rank of this job)
from mpi4py import MPI

import impact_fenics  # noqa: F401  (PETSc starts on every rank, collectively, at import)

COMM = MPI.COMM_WORLD

MODULE = textwrap.dedent('''
    from numba import njit


    @njit(cache=True)
    def value():
        return {value}
''')


def _cold_share(root: str, call: bool) -> float:
    """jit_watch.cold_share of the kernels a.value and b.value, in a new process that
    imports a scratch package of two modules (a, b) of one cached kernel each, then
    (``call``) calls both kernels (compiled or loaded)."""
    code = ("import sys; sys.path.insert(0, sys.argv[1]);"
            "from impact_fenics_scratch import a, b; from impact_fenics.jit_watch import "
            "cold_share; print(cold_share((a.value, b.value)));"
            + ("a.value(); b.value()" if call else ""))
    out = subprocess.run([sys.executable, "-c", code, root], capture_output=True, text=True,
                         check=True, env=clean_mpi_env()).stdout
    return float(out)


def test_a_cold_cache_is_seen_before_anything_compiles(tmp_path):
    """A first run (nothing cached): 1; everything cached: 0; one of the two modules
    edited (its cache stale): 1/2 of the kernels compile again."""
    if COMM.rank != 0:  # one process writes the scratch package
        return
    package = tmp_path / "impact_fenics_scratch"
    package.mkdir()
    (package / "__init__.py").write_text("")
    (package / "a.py").write_text(MODULE.format(value=1))
    (package / "b.py").write_text(MODULE.format(value=2))
    assert _cold_share(str(tmp_path), call=True) == 1.0
    assert _cold_share(str(tmp_path), call=False) == 0.0
    past = time.time() - 60.0  # the caches made a minute ago, then b edited
    for entry in (package / "__pycache__").iterdir():
        os.utime(entry, (past, past))
    (package / "b.py").write_text(MODULE.format(value=3))
    assert _cold_share(str(tmp_path), call=False) == 0.5
