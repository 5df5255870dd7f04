"""impact_fenics: explicit transient dynamics with contact on axisymmetric solids (see README)."""
import os as _os

# numba colours its messages with colorama when that is installed, and colorama then
# writes a terminal reset code at exit: a stray escape code on the console of every run
_os.environ.setdefault("NUMBA_DISABLE_ERROR_MESSAGE_HIGHLIGHTING", "1")

# One BLAS thread per MPI rank unless the user chose otherwise: Debian's stack links
# the serial OpenBLAS; the wheels' numpy and SciPy bring threaded ones, which on a
# loaded machine or under mpirun oversubscribe the cores (read when BLAS loads, so
# set before numpy/SciPy are imported).
_os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

# mpi4py.MPI before anything that loads dolfinx or petsc4py: the PyPI wheels of the
# current FEniCSx find libmpi only once mpi4py has loaded it (impact_fenics.compat).
from . import interrupts as _interrupts  # noqa: E402  (no MPI, no dolfinx)

with _interrupts.held_at_start():  # a signal during MPI's start-up: one line, exit 130/143
    from mpi4py import MPI as _MPI  # noqa: F401

    # PETSc's own SIGINT/SIGTERM handlers (the wheels' PETSc installs them) would abort
    # where ours stop a run cleanly: keep them off, unless PETSc is up already
    import sys as _sys

    if "petsc4py.PETSc" not in _sys.modules:
        import petsc4py as _petsc4py

        _petsc4py.init(["impact_fenics", "-no_signal_handler"])  # (program name, option)

# numba's on-disk cache of the package's kernels is valid for the sources that filled it
# only (kernel_cache): swept before any kernel loads, once for ranks that import at once
from . import kernel_cache as _kernel_cache  # noqa: E402

_kernel_cache.sweep(_os.path.dirname(_os.path.abspath(__file__)))
