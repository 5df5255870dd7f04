# impact_fenics in two images, one per FEniCSx stack.
#
# Debian bookworm, FEniCSx 0.5.2 from Debian's packages (the default target):
#   Build:  docker build -t impact_fenics .
#   Check:  docker run --rm impact_fenics            (runs `make test`)
#   Demo:   docker run --rm impact_fenics make demo
#   Scene:  docker run --rm -v "$PWD/results:/opt/impact_fenics/results" impact_fenics \
#               scripts/mpirun.sh -n 2 .venv/bin/impact-fenics run scenes/bar_impact.toml
#
# The current FEniCSx, dolfinx 0.11 from the PyPI wheels (PETSc 3.25, MPICH) on
# Python 3.12 (bookworm underneath):
#   Build:  docker build --target modern -t impact_fenics:modern .
#   Check:  docker run --rm impact_fenics:modern     (runs `make test-modern`)
#   Demo:   docker run --rm impact_fenics:modern make demo-modern
#   Scene:  docker run --rm -v "$PWD/results:/opt/impact_fenics/results" impact_fenics:modern \
#               scripts/mpirun.sh -n 2 .venv-modern/bin/impact-fenics run scenes/bar_impact.toml

# ---------------------------------------------------------------- modern
FROM python:3.12-slim-bookworm AS modern

ENV DEBIAN_FRONTEND=noninteractive
# make; gcc for the form compiler's JIT (the image has Python's headers); the
# libraries that VTK (pyvista) loads for off-screen rendering (with their
# recommended Mesa drivers, as in the debian stage)
RUN apt-get update \
 && apt-get install -y make gcc libc6-dev libgl1 libegl1 \
    libx11-6 libxrender1 \
 && rm -rf /var/lib/apt/lists/*

WORKDIR /opt/impact_fenics
COPY . .
# python3 on PATH is 3.12: scripts/setup_modern.sh takes it for .venv-modern
RUN rm -rf .venv .venv-modern results ./*.egg-info \
 && make setup-modern

CMD ["make", "test-modern"]

# ---------------------------------------------------------------- debian (default)
FROM debian:bookworm AS debian

ENV DEBIAN_FRONTEND=noninteractive \
    OMPI_ALLOW_RUN_AS_ROOT=1 \
    OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 \
    OMPI_MCA_rmaps_base_oversubscribe=1

# make and ca-certificates first: the rest is exactly the PACKAGES list of
# scripts/setup.sh, listed here too so that the image layer caches it (and
# setup.sh then finds nothing missing).
RUN apt-get update \
 && apt-get install -y make ca-certificates \
    python3-dolfinx python3-petsc4py python3-mpi4py python3-ufl python3-basix \
    python3-gmsh openmpi-bin python3-scipy python3-matplotlib python3-pytest \
    python3-venv python3-slepc4py gcc libgl1 libegl1 libx11-6 libxrender1 \
    python3-h5py python3-setuptools python3-wheel libopenblas0-serial \
 && rm -rf /var/lib/apt/lists/*

WORKDIR /opt/impact_fenics
COPY . .
# A venv or results copied from a working tree belong to another path: start clean.
RUN rm -rf .venv .venv-modern results ./*.egg-info \
 && make setup

CMD ["make", "test"]
