"""A small-strain scene's [wall]: an elastic bar (nu = 0) dropped onto the fixed plane.

The wall is a fixed rigid part with a contact set over every boundary node (as the
finite-strain run's). Oracles, for each method (FILM, DME, penalty "scaled"):

* momentum: each step the bar's z momentum changes by -h times the wall's force (the
  internal forces sum to zero in z, a rigid translation being free), so the history's
  momentum_z after the last step equals -M v0 + sum_n h_n F_n to round-off (a sum of
  n_steps products, each within EPS of its size; the internal forces' z sum is the
  round-off of a row of K times |u|, on the scale of the peak force);
* the contact time of a plane wave (nu = 0: the 1D solution is exact in the continuum):
  the bar is on the wall for 2 L / c0, c0 = sqrt(E / rho); the discrete front spreads
  over about a cell at the wall and at the free end, and the release is seen within a
  step: |T - 2 L / c0| <= 2 h / c0 + 2 dt;
* the energy the wall takes: the face layer's kinetic energy, K0 h / (2 L) exactly
  (see the test), at n_r = 4 and 8;
* the ledger: the summary's balance error within roundoff.ledger.
"""
import json
import os

import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics import cli
from roundoff import EPS, ledger

COMM = MPI.COMM_WORLD
R, L, E, RHO, V0 = 0.005, 0.05, 200e9, 7850.0, 5.0  # m, m, Pa, kg/m^3, m/s
C0 = (E / RHO) ** 0.5
SCENE = """title = "elastic bar on a rigid wall"
[mesh]
generator = "quad_bar"
radius = {R!r}
length = {L!r}
n_r = {n_r}

[materials.steel]
model = "elastic"
E = {E!r}
nu = 0.0
density = {RHO!r}

[bodies.bar]
material = "steel"
velocity = [0.0, -{V0!r}]

[wall]
z = 0.0
method = "{method}"

[time]
t_end = 30e-6
cfl = 0.5

[output]
history_every = 1
energy_every = 1
fields = false
plots = false
"""


def _run(tmp, method: str, n_r: int):
    out = os.path.join(tmp, f"{method}_{n_r}")
    scene = os.path.join(tmp, f"{method}_{n_r}.toml")
    if COMM.rank == 0:
        with open(scene, "w") as f:
            f.write(SCENE.format(R=R, L=L, E=E, RHO=RHO, V0=V0, n_r=n_r, method=method))
    COMM.barrier()
    assert cli.main(["run", scene, "--out", out, "--quiet"]) == 0
    with open(os.path.join(out, "summary.json")) as f:
        summary = json.load(f)
    history = np.genfromtxt(os.path.join(out, "history.csv"), delimiter=",", names=True)
    energy = np.genfromtxt(os.path.join(out, "energy.csv"), delimiter=",", names=True)
    return summary, history, energy


@pytest.fixture(scope="module")
def tmp(tmp_path_factory):
    path = str(tmp_path_factory.mktemp("wall")) if COMM.rank == 0 else None
    return COMM.bcast(path)


@pytest.mark.parametrize("method", ["film", "dme", "penalty"])
def test_an_elastic_bar_rebounds_from_the_wall(tmp, method):
    s, h, e = _run(tmp, method, 4)
    assert s["status"].startswith("completed")
    mass = RHO * np.pi * R ** 2 * L
    dt = float(h["dt"][-1])
    force = h["wall_force"]
    # momentum: p_N = -M v0 + sum h F (the history's rows are the steps 1..N)
    p_end = float(e["momentum_z"][-1])
    impulse = float(np.sum(h["dt"] * force))
    scale = mass * V0 + impulse
    assert abs(p_end - (-mass * V0 + impulse)) <= EPS * (4 * len(force)) * scale
    # the contact time of the plane wave
    on = np.flatnonzero(force > 0.0)
    t_contact = float(h["time"][on[-1]] - h["time"][on[0]] + dt)
    h_cell = R / 4
    assert abs(t_contact - 2 * L / C0) <= 2 * h_cell / C0 + 2 * dt
    assert s["energy_balance_error_rel"] <= ledger(s["n_steps"], s["n_dofs"])


@pytest.mark.parametrize("n_r", [4, 8])
@pytest.mark.parametrize("method", ["film", "dme", "penalty"])
def test_the_wall_takes_the_face_layer_kinetic_energy(tmp, method, n_r):
    """The face's nodes stop on the wall at the first step and keep nothing of their
    kinetic energy; after that the plane wave runs without loss (the face stays on the
    wall until the whole bar releases). So the energy left at the end is
    K0 - 1/2 m_face v0^2, m_face the lumped mass of the face's nodes: on Q1, the row sums
    of the bottom row of cells' mass, where the bottom nodes' shape functions sum to
    1 - zeta (zeta across the row, 0 to 1), whose integral with 2 pi r is half the row's:
    m_face = 1/2 rho pi R^2 h, so the loss is K0 h / (2 L), to the ledger's round-off.

    The ledger sees it from its first row: E_0 is the initial state, K0 (the lumped
    masses sum to the bar's), and the contact work books the loss. With FILM and DME the
    face stops within the first step (its nodes at rest, unloaded: u^0 = 0), so the first
    row's contact work is already -1/2 m_face v0^2 (the penalty's springs take it over a
    few steps)."""
    s, _, e = _run(tmp, method, n_r)
    mass = RHO * np.pi * R ** 2 * L
    k0 = 0.5 * mass * V0 ** 2
    h_cell = R / n_r  # quad_bar: square cells
    left = float(e["kinetic"][-1] + e["strain"][-1])
    bound = ledger(s["n_steps"], s["n_dofs"])
    assert abs((k0 - left) / k0 - h_cell / (2 * L)) <= bound
    assert abs(s["energy_initial"] - k0) <= bound * k0
    assert abs(-e["contact_work"][-1] / k0 - h_cell / (2 * L)) <= bound
    if method != "penalty":
        assert abs(-e["contact_work"][0] / k0 - h_cell / (2 * L)) <= bound
