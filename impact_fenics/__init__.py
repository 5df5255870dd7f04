"""impact_fenics: explicit transient dynamics with contact on FEniCSx (see README)."""
# mpi4py.MPI before anything that loads dolfinx or petsc4py: the PyPI wheels of the
# current FEniCSx find libmpi only once mpi4py has loaded it (impact_fenics.compat).
from mpi4py import MPI as _MPI  # noqa: F401
