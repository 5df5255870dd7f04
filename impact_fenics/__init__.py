"""impact_fenics: explicit transient dynamics with contact on FEniCSx (see README)."""
import os as _os

# One BLAS thread per MPI rank unless the user chose otherwise: Debian's stack links
# the serial OpenBLAS; the wheels' numpy and SciPy bring threaded ones, which on a
# loaded machine or under mpirun oversubscribe the cores (read when BLAS loads, so
# set before numpy/SciPy are imported).
_os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

# mpi4py.MPI before anything that loads dolfinx or petsc4py: the PyPI wheels of the
# current FEniCSx find libmpi only once mpi4py has loaded it (impact_fenics.compat).
from mpi4py import MPI as _MPI  # noqa: E402,F401
