"""numba's on-disk cache of a kernel that calls another module's kernel goes when that
module changes (jit_watch.drop_stale_cache).

numba checks a cached kernel against its own source file only: a kernel compiled
with another module's kernel inside it would keep the old code of that kernel after
an edit. The oracle is the file system and the value computed: a scratch package
with a caller and a callee module, the caller compiled and cached, the callee edited
(a newer file with another constant), and the caller, imported anew, must compute
with the new constant; the same import without the edit keeps the cache.
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

CALLER = textwrap.dedent('''
    from numba import njit
    from impact_fenics.jit_watch import drop_stale_cache
    from . import callee
    from .callee import constant


    @njit(cache=True)
    def twice():
        return 2 * constant()


    drop_stale_cache(twice, (callee,))
''')

CALLEE = textwrap.dedent('''
    from numba import njit


    @njit(cache=True)
    def constant():
        return {value}
''')


def _value(root: str) -> tuple[int, int]:
    """(twice(), cache entries of twice before the call) in a new process."""
    code = ("import glob, os, sys; sys.path.insert(0, sys.argv[1]); import scratch.caller as c;"
            "n = len(glob.glob(os.path.join(sys.argv[1], 'scratch', '__pycache__', "
            "'caller.twice-*')));"
            "print(c.twice(), n)")
    out = subprocess.run([sys.executable, "-c", code, root], capture_output=True, text=True,
                         check=True, env=clean_mpi_env()).stdout.split()
    return int(out[0]), int(out[1])


def test_an_edited_callee_drops_the_callers_cache(tmp_path):
    if COMM.rank != 0:  # one process writes the scratch package
        return
    package = tmp_path / "scratch"
    package.mkdir()
    (package / "__init__.py").write_text("")
    (package / "caller.py").write_text(CALLER)
    (package / "callee.py").write_text(CALLEE.format(value=3))
    assert _value(str(tmp_path)) == (6, 0)  # compiled, then cached
    assert _value(str(tmp_path)) == (6, 2)  # loaded from its cache (index and data)
    # the cache made a minute ago (whatever the file system's clock step), then the edit
    past = time.time() - 60.0
    for entry in (package / "__pycache__").iterdir():
        os.utime(entry, (past, past))
    (package / "callee.py").write_text(CALLEE.format(value=5))
    assert _value(str(tmp_path)) == (10, 0)  # the stale cache went: the new constant
    assert _value(str(tmp_path)) == (10, 2)  # and the new one stays


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
