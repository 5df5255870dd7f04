"""The machine and the software stack a run was taken on (the JSON's ``meta``)."""
from __future__ import annotations

import os
import platform

import numpy as np
from mpi4py import MPI


def _first_field(path: str, prefix: str) -> str | None:
    """The text after ':' of the first line of ``path`` starting with ``prefix``."""
    try:
        with open(path) as f:
            for line in f:
                if line.startswith(prefix):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return None


def machine_info(comm: MPI.Comm) -> dict:
    import scipy
    from petsc4py import PETSc

    from ..compat import versions

    stack = versions()

    cpu = _first_field("/proc/cpuinfo", "model name") or "unknown"
    mem = _first_field("/proc/meminfo", "MemTotal")
    try:
        mem_gb = int(mem.split()[0]) / 2 ** 20 if mem else None
    except (ValueError, IndexError):
        mem_gb = None
    blas = None
    for lib in ("/usr/lib/x86_64-linux-gnu/libblas.so.3", "/usr/lib/aarch64-linux-gnu/libblas.so.3"):
        if os.path.exists(lib):
            blas = os.path.realpath(lib)
    try:
        affinity = len(os.sched_getaffinity(0))
    except AttributeError:
        affinity = os.cpu_count()
    return {
        "cpu_model": cpu,
        "cores": os.cpu_count(),
        "cores_usable": affinity,
        "memory_gb": mem_gb,
        "hostname": platform.node(),
        "ranks": comm.size,
        "python": platform.python_version(),
        "dolfinx": stack["dolfinx"],
        "petsc": stack["petsc"],
        "petsc4py": stack["petsc4py"],
        "petsc_int_bytes": np.dtype(PETSc.IntType).itemsize,
        "mpi": stack["mpi"],
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "blas": blas,
        "openblas_env": {k: v for k, v in os.environ.items() if k.startswith("OPENBLAS_")},
        "load_average": os.getloadavg(),
    }
