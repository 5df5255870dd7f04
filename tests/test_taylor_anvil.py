"""The Taylor rod onto a deformable anvil (short runs; the convergence to the rigid wall
is the study tests/test_taylor_anvil_study.py).

Scene (:func:`impact_fenics.scenes.taylor_anvil`): the copper rod of docs/taylor_bar.md
(finite-strain J2 on Q1, R = 3.2 mm, L = 32.4 mm, n_r = 4) onto a steel anvil (linear
elastic, small strain, Q1, 3 R wide and 2 R deep), two cell groups of one mesh whose faces
share no node, node-to-segment contact (the rod's face the slave) re-paired every 5 steps,
a fixed step (the segment kind takes a constant one) under the step that follows the rod's
cells.

Oracles:

* z momentum: with the anvil free (no dof held in z, no load) no external force acts in
  z, so the total z momentum (rod + anvil) keeps its initial value to the round-off of a
  ledger (roundoff.ledger: the contact forces G' lam are equal and opposite only up to
  their roundings, the finite force's and K's rows sum to zero only up to theirs);
* the ledger: kinetic + strain + plastic + work gap - contact work = E_0, the kinetic
  identity of the half-step scheme, within roundoff.ledger at every row;
* re-pairing: at every re-pairing the pairs and rows of G equal a brute-force projection
  of every slave onto every segment (test_contact_repair._Watch);
* first touch, elastic (5 m/s: at most Z_rod v0 = 0.2 GPa, half the 400 MPa yield): the
  stress across the interface is the 1D two-impedance value sigma = Z1 Z2 v0 / (Z1 + Z2),
  Z = rho c_P the impedance of a plane wave of uniaxial strain (the state under a face
  struck as a whole), for the steel anvil (Z1 / Z2 = 0.89) and the one 100 times stiffer
  (0.0089), read on the anvil's axis half a cell below its face until the release from the
  loaded area's edge (r = R) reaches it.
"""
import math

import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics import scenes
from impact_fenics.materials import STEEL, FiniteJ2
from impact_fenics.simulation import Settings
from roundoff import ledger
from test_contact_repair import _Watch

COMM = MPI.COMM_WORLD
R, L = 3.2e-3, 32.4e-3  # m, the rod's radius and length (docs/taylor_bar.md)
COPPER = FiniteJ2(E=117e9, nu=0.35, density=8930.0, yield_stress=400e6, hardening=100e6)
DT = 2.0 ** -27  # s (7.5e-9: 0.07 of the limit at set-up, the anvil's 1.1e-7 s; a power
# of two, so that t = n DT is exact and the run ends in equal steps)


def _settings() -> Settings:
    return Settings(quiet=True, plots=False, timers=False, fields=False, energy_every=1)


def _anvil(n_steps: int, v0: float, method: str = "film", anvil_scale: float = 1.0,
           hold_anvil: bool = False, dt: float = DT):
    return scenes.taylor_anvil(_settings(), COPPER, anvil_scale=anvil_scale, n_r=4, v0=v0,
                               method=method, hold_anvil=hold_anvil, t_end=n_steps * dt,
                               dt=dt)


@pytest.mark.parametrize("method", ["film", "dme"])
def test_momentum_ledger_and_repairing(method):
    """227 m/s, 400 steps (3 us: the rim yields and starts to spread), the anvil free:
    z momentum and the ledger within roundoff.ledger, every re-pairing the brute force's."""
    sim = _anvil(400, 227.0, method)
    watch = _Watch(sim)
    summary = sim.run(extra=sim.scene_figures)
    assert sim.status == "completed" and summary["n_steps"] == 400
    e = sim.energy.data()
    n_dofs = COMM.allreduce(sim.model.n_owned)
    bound = ledger(sim.n_steps, n_dofs)
    p = e["momentum_z"]
    assert np.abs(p - p[0]).max() <= bound * abs(p[0])
    assert np.abs(e["balance_error"]).max() <= bound * sim.ledger.E0
    assert e["plastic_work"][-1] > 0.0  # the rod yields at 227 m/s
    assert len(watch.steps) == sim.contacts[0].repairs == 400 // 5
    # the figures are the rod's (the anvil's nodes at (0, 0) and (R, 0) are left out):
    # its rim has spread, its axis has shortened
    assert summary["final_face_radius"] > R and summary["final_length"] < L


def _z(material) -> float:
    """rho c_P (kg/m^2/s): the impedance of a plane (uniaxial-strain) wave."""
    nu = material.nu
    m = material.E * (1 - nu) / ((1 + nu) * (1 - 2 * nu))
    return math.sqrt(m * material.density)


@pytest.mark.parametrize("n_r", [4, 8])
@pytest.mark.parametrize("anvil_scale", [1.0, 100.0])
def test_first_touch_stress_is_the_two_impedance_value(anvil_scale, n_r):
    """5 m/s, the anvil free: the anvil's sigma_zz at (0, -h/2) averaged from the front's
    arrival plus one cell's rise, (h/2 + h) / c2, to the release from the loaded area's edge,
    sqrt(R^2 + (h/2)^2) / c2, against Z1 Z2 v0 / (Z1 + Z2). The discrete front rises over
    about a cell's transit h / c2 and rings behind it (a lumped-mass mesh's dispersion)
    with a period of the same order: over a window T the mean errs by at most the
    fraction (h / c2) / T (0.40 at n_r = 4, 0.15 at n_r = 8), which still tells the two
    anvils apart (their values differ by a factor 1.87)."""
    v0, dt, h = 5.0, 2.0 ** -28, R / n_r
    z1, z2 = _z(COPPER), anvil_scale * _z(STEEL)
    c2 = math.sqrt(STEEL.E * (1 - STEEL.nu) / ((1 + STEEL.nu) * (1 - 2 * STEEL.nu))
                   / STEEL.density)  # m/s, the anvil's plane-wave speed (scale-free)
    t_a, t_b = 1.5 * h / c2, math.hypot(R, 0.5 * h) / c2
    sim = scenes.taylor_anvil(_settings(), COPPER, anvil_scale=anvil_scale, n_r=n_r, v0=v0,
                              hold_anvil=False, t_end=math.ceil(t_b / dt) * dt, dt=dt)
    sim.add_probe("sigma_zz_anvil", (0.01 * h, -0.5 * h), "sigma_zz")
    sim.run()
    hist = sim.history.data()
    t, sigma = np.asarray(hist["time"]), -np.asarray(hist["sigma_zz_anvil"])
    window = (t >= t_a) & (t <= t_b)
    expected = z1 * z2 * v0 / (z1 + z2)
    assert sigma[window].mean() == pytest.approx(expected, rel=(h / c2) / (t_b - t_a))
    e = sim.energy.data()
    assert not e["plastic_work"].any()  # elastic


def test_the_mesh_holds_two_bodies_that_share_no_node():
    """quad_meshes.rod_on_anvil through the scene: each body's lumped mass (the row sums
    rho int N_a 2 pi r dA over its own nodes) adds up to rho V of its cylinder, pi R^2 L and
    pi (3R)^2 2R, to the round-off of a node's mass (about 30 roundings) and of the sum (one
    a node): the bodies' nodes are disjoint and their cells fill the two cylinders."""
    from roundoff import rounding

    sim = _anvil(1, 227.0)
    model, mass = sim.model, sim.integrator.mass
    for body, density, volume in (("rod", COPPER.density, math.pi * R ** 2 * L),
                                  ("anvil", STEEL.density, math.pi * (3 * R) ** 2 * 2 * R)):
        z = model.body_dofs(body, 1)
        total = COMM.allreduce(float(mass[z].sum()))
        n = COMM.allreduce(z.size)
        assert abs(total - density * volume) <= rounding(30 + n, density * volume)
    rod, anvil = (set(model.to_global(model.body_dofs(b, 1)).tolist()) for b in ("rod", "anvil"))
    assert not COMM.allreduce(len(rod & anvil))  # owned dofs: each node once over the ranks


def test_an_anvil_narrower_than_the_rod_is_refused():
    from impact_fenics.errors import InputError

    with pytest.raises(InputError, match="anvil radius"):
        scenes.taylor_anvil(_settings(), COPPER, anvil_radius=0.5 * R, t_end=DT, dt=DT)
