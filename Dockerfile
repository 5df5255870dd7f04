# impact_fenics on Debian bookworm, with FEniCSx from Debian's packages.
# Build:  docker build -t impact_fenics .
# Check:  docker run --rm impact_fenics            (runs `make test`)
# Demo:   docker run --rm impact_fenics make demo
# Scene:  docker run --rm -v "$PWD/results:/opt/impact_fenics/results" impact_fenics \
#             scripts/mpirun.sh -n 2 .venv/bin/impact-fenics run scenes/bar_impact.toml
FROM debian:bookworm

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
RUN rm -rf .venv results ./*.egg-info \
 && make setup

CMD ["make", "test"]
