"""numba's on-disk cache of the package's kernels runs the code of the present sources
(kernel_cache).

numba keys a cached kernel by its own file. Two ways a cache made elsewhere ran
other code than the sources say, and their oracles, each in new processes that
share one cache directory (the value a kernel computes is the evidence; the
expected value is the one a process computes alone from the present sources):

- an edited module whose kernel and constant another module's kernel took in:
  the package's sweep at import deletes the cache, the new value comes out;
- closures of one factory, cached inside two kernels by two processes: each keeps
  its own code when one process loads both (with one name for every closure,
  numba 0.60 and 0.68 linked both kernels to the first-loaded closure: a kernel
  of the package ran another contact method's face step that way). The package's
  own cached kernels are checked to have a name each.
"""
import importlib
import os
import pkgutil
import subprocess
import sys
import textwrap

from conftest import clean_mpi_env  # (under mpirun: the child is not a rank of this job)
from mpi4py import MPI

import impact_fenics

COMM = MPI.COMM_WORLD

INIT = textwrap.dedent('''
    import os
    from impact_fenics.kernel_cache import sweep
    sweep(os.path.dirname(os.path.abspath(__file__)))
''')

CALLER = textwrap.dedent('''
    from numba import njit
    from .callee import SCALE, constant


    @njit(cache=True)
    def scaled():
        return SCALE * constant()
''')

CALLEE = textwrap.dedent('''
    from numba import njit

    SCALE = {scale}


    @njit(cache=True)
    def constant():
        return {value}
''')


def _run(root: str, package: str, code: str) -> list[str]:
    """Run ``code`` (after ``import <package>.<module> as m`` lines it holds) in a new
    Python process with ``root`` first on its path; its printed words."""
    prelude = f"import sys; sys.path.insert(0, {root!r}); import numpy as np;"
    out = subprocess.run([sys.executable, "-c", prelude + code], capture_output=True,
                         text=True, check=True, env=clean_mpi_env()).stdout
    return out.split()


def _entries(cache: str, stem: str) -> int:
    return sum(n.startswith(stem + ".") and n.endswith((".nbi", ".nbc"))
               for n in os.listdir(cache)) if os.path.isdir(cache) else 0


def test_an_edited_module_sweeps_the_cache_of_the_kernels_that_took_it_in(tmp_path):
    """The caller's kernel compiles the callee's kernel and constant into itself; numba
    alone would keep 2 x 3 after the callee becomes 5 and 71 (it checks the caller's file
    only). Files of the cache directory that are not numba's cache of the package's
    modules stay."""
    if COMM.rank != 0:  # one process writes the scratch package
        return
    package = tmp_path / "scratch_sweep"
    package.mkdir()
    (package / "__init__.py").write_text(INIT)
    (package / "caller.py").write_text(CALLER)
    (package / "callee.py").write_text(CALLEE.format(scale=2, value=3))
    cache = str(package / "__pycache__")
    code = "import scratch_sweep.caller as m; print(m.scaled())"
    assert _run(str(tmp_path), "scratch_sweep", code) == ["6"]  # compiled, then cached
    assert _entries(cache, "caller") == 2  # index and data
    foreign = [os.path.join(cache, n) for n in ("notes.txt", "other.kernel-1.py311.nbi")]
    for name in foreign:
        open(name, "w").close()
    assert _run(str(tmp_path), "scratch_sweep", code) == ["6"]  # loaded: nothing swept
    assert _entries(cache, "caller") == 2
    # (a value of another length: Python's own .pyc check is the file's second and size)
    (package / "callee.py").write_text(CALLEE.format(scale=5, value=71))
    assert _run(str(tmp_path), "scratch_sweep", code) == ["355"]  # swept: the new code
    assert _entries(cache, "caller") == 2  # cached anew
    assert all(os.path.exists(name) for name in foreign)


FACTORY = textwrap.dedent('''
    import numpy as np
    from numba import njit


    def _make(k):
        def closure(x):  # a loop LLVM does not inline into the caller
            s = 0.0
            for i in range(x.size):
                for j in range(x.size):
                    s += np.sin(x[i] * k + j) * np.cos(x[j] - k) / (1.0 + x[i] ** 2 + k)
                    if s > 1e9:
                        s = np.sqrt(s) + np.exp(-x[j])
            return k * (x[0] + s)

        closure.__name__ = closure.__qualname__ = f"closure_{k}"  # the package's rule
        return njit(cache=True)(closure)


    _one, _two = _make(1), _make(2)


    @njit(cache=True)
    def one(x):
        return _one(x)


    @njit(cache=True)
    def two(x):
        return _two(x)
''')


def test_closures_of_one_factory_keep_their_code_across_two_processes_caches(tmp_path):
    """Process A caches ``one`` alone, process B ``two`` alone (so their closures get the
    same counter); a third loads both and must compute what A and B did, bit for bit
    (printed with repr: 17 digits)."""
    if COMM.rank != 0:
        return
    package = tmp_path / "scratch_closures"
    package.mkdir()
    (package / "__init__.py").write_text("")
    (package / "factory.py").write_text(FACTORY)
    call = "import scratch_closures.factory as m; x = np.linspace(0.1, 0.9, 5);"
    alone_one = _run(str(tmp_path), "", call + "print(repr(m.one(x)))")
    alone_two = _run(str(tmp_path), "", call + "print(repr(m.two(x)))")
    assert alone_one != alone_two
    both = _run(str(tmp_path), "", call + "print(repr(m.one(x)), repr(m.two(x)))")
    assert both == alone_one + alone_two
    both = _run(str(tmp_path), "", call + "print(repr(m.two(x)), repr(m.one(x)))")
    assert both == alone_two + alone_one


def _cached_kernels() -> list:
    """Every numba kernel with an on-disk cache bound in the package's modules, also
    inside a dict, tuple or list there (a factory's kernels)."""
    from numba.core.dispatcher import Dispatcher

    for info in pkgutil.walk_packages(impact_fenics.__path__, "impact_fenics."):
        if not info.name.endswith("__main__"):  # (a command line: runs on import)
            importlib.import_module(info.name)
    found = []
    for name, module in list(sys.modules.items()):
        if module is None or not name.startswith("impact_fenics"):
            continue
        for obj in list(vars(module).values()):
            items = obj.values() if isinstance(obj, dict) else \
                obj if isinstance(obj, (tuple, list)) else (obj,)
            found += [k for k in items if isinstance(k, Dispatcher)
                      and type(k._cache).__name__ != "NullCache"]
    return found


def test_each_cached_kernel_of_the_package_has_a_name_of_its_own():
    """No two cached kernels (distinct Python functions) share module and qualified name."""
    by_name: dict[tuple[str, str], set[int]] = {}
    kernels = _cached_kernels()
    for k in kernels:
        by_name.setdefault((k.py_func.__module__, k.py_func.__qualname__), set()).add(
            id(k.py_func))
    shared = {name: len(ids) for name, ids in by_name.items() if len(ids) > 1}
    assert len(kernels) > 100 and not shared, shared
