"""Test set-up shared by the serial and the MPI runs.

Under mpirun a failure on one rank must not leave the others waiting in a
collective: any failing test aborts every rank.
"""
import logging

import pytest
from mpi4py import MPI

logging.getLogger().setLevel(logging.WARNING)  # the form compiler logs at INFO


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()
    if MPI.COMM_WORLD.size > 1 and report.failed:
        import sys

        sys.stderr.write(f"\n[rank {MPI.COMM_WORLD.rank}] {item.nodeid} failed:\n"
                         f"{report.longreprtext}\n")
        sys.stderr.flush()
        MPI.COMM_WORLD.Abort(1)


@pytest.fixture
def comm():
    return MPI.COMM_WORLD


@pytest.fixture(scope="module")
def punch_mesh():
    """A small punch block (the paper's punch scene at R_z = 1 m, coarse): 21 constraints."""
    from impact_fenics import meshing

    return meshing.punch_block(width=1.5, depth=0.5, h_surface=0.05, grading=1.0, h_max=0.25,
                               breaks=((1.0, 20),))


def load_demo(name: str):
    """Import demos/<name>.py as a module (its run() and checks are the tested API)."""
    import importlib.util
    import os

    path = os.path.join(os.path.dirname(__file__), "..", "demos", f"{name}.py")
    spec = importlib.util.spec_from_file_location(f"demo_{name}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def gather_field(model, values):
    """(coordinates, values) of an owned dof array, gathered and sorted by node on every rank."""
    import numpy as np

    xy = model.node_xy[: model.n_owned // 2]
    vals = values.reshape(-1, 2)
    all_xy = np.concatenate(model.comm.allgather(xy))
    all_v = np.concatenate(model.comm.allgather(vals))
    key = np.round(all_xy, 10)  # coordinates equal up to round-off sort alike
    # coincident nodes of two bodies (a contact face) are told apart by their values
    order = np.lexsort((all_v[:, 1], all_v[:, 0], key[:, 1], key[:, 0]))
    return all_xy[order], all_v[order]


def clean_mpi_env() -> dict:
    """The environment without this process's MPI variables, for launching mpirun anew."""
    from impact_fenics.compat import clean_launcher_env

    return clean_launcher_env()


# ------------------------------------------------- the nu = 0 bar under an end pressure
# shared by the strain-gauge and the section tests: one run per mesh size for both
WAVE_PEAK, WAVE_RISE, WAVE_END = 100e6, 2e-5, 2.1e-4  # Pa, s, s: the far end's reflection later
WAVE_RADIUS, WAVE_STATIONS, WAVE_GAUGE = 0.05, (0.3, 0.6), 2e-3  # m


@pytest.fixture(scope="session")
def wave_bars():
    """{h: the run}: scenes.elastic_bar (nu = 0, radius WAVE_RADIUS) under the end pressure
    WAVE_PEAK rising over WAVE_RISE, at h = 0.01 and 0.005 m, with a strain gauge of length
    WAVE_GAUGE on the surface (``gauge_k``) and a section (``section_k``) at each of
    WAVE_STATIONS."""
    from impact_fenics import scenes
    from impact_fenics.simulation import Settings

    runs = {}
    for h in (0.01, 0.005):
        settings = Settings(cfl=0.9, t_end=WAVE_END, out=None, quiet=True)
        sim = scenes.elastic_bar(settings, h=h, nu=0.0, peak=WAVE_PEAK, t_rise=WAVE_RISE,
                                 radius=WAVE_RADIUS, comm=MPI.COMM_WORLD)
        for k, z in enumerate(WAVE_STATIONS):
            sim.add_probe(f"gauge_{k}", (WAVE_RADIUS, z), "strain_gauge", WAVE_GAUGE)
            sim.add_probe(f"section_{k}", (0.0, z), "section")
        sim.run()
        runs[h] = sim
    return runs


def wave_plateau(t, values, exact: float) -> tuple[float, float]:
    """(the plateau, the arrival time (s)) of a probe's history ``values`` at times ``t``
    under the pulse of :func:`wave_bars` whose held value is ``exact``: the arrival where
    half of it is reached, the plateau the mean from 30 to 70 us after (the held part)."""
    import numpy as np

    from impact_fenics.probes import arrival_time

    arrival = arrival_time(t, values / exact, 0.5)
    window = (t > arrival + 3e-5) & (t < arrival + 7e-5)
    return float(np.mean(values[window])), arrival
