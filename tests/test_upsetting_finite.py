"""Upsetting at finite strain, short: the ledger, the Coulomb cone and the frictionless pressure.

A J2 cylinder at finite strain (perfectly plastic, sigma_y; R0 = H0 = 5 mm, H/D = 0.5, 4 x 4
Q1 cells) on the fixed plane z = 0, compressed by a rigid platen on its top face
(scenes.upsetting: the platen is a crosshead of prescribed velocity, ramped to V over
t_ramp, 22 elastic transit times H0/c, and held), DME on both faces with the same mu. The
oracles do not come from the code:

- the ledger K + W_int + L = W_ext closes within roundoff.ledger (each step's roundings;
  W_ext the crosshead's work, - sum h 1/2 (v^{n-1/2} + v^{n+1/2}) R^n, docs/friction.md 12);
- the Coulomb cone: at every active pair and every step |lambda_t| <= mu lambda_n;
- mu = 0: the compression is homogeneous, a uniaxial Kirchhoff stress at yield, tau_zz =
  -sigma_y, so the Cauchy stress is sigma_y / J with J = exp(-sigma_y / (3K)) (Hencky: the
  log volume strain is tr tau / (3K)); the platen force over the top face's current area
  pi r_top^2, read while the cylinder flows, equals it within the ringing (the spread of
  the sampled values), and within the impedance pressure rho c V (the largest dynamic
  overpressure a platen at speed V makes on the elastic body); the current area being
  J pi R_eq^2 (R_eq^2 = R0^2 H0 / H), p = F / (pi R_eq^2) is sigma_y itself.

The same test runs unchanged on 1, 2 and 3 ranks; the finite-strain study with the slab
estimate is tests/test_upsetting_finite_study.py (docs/friction.md).
"""
import math

import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics import scenes
from impact_fenics.materials.finite_j2 import FiniteJ2
from impact_fenics.simulation import Settings
from roundoff import ledger
from scene_texts import read_history

COMM = MPI.COMM_WORLD
R0 = H0 = 5e-3  # m (H/D = 0.5)
E, NU, RHO, SIGMA_Y = 20e9, 0.3, 7850.0, 200e6  # Pa, -, kg/m^3, Pa (yield strain 1 %)
C = math.sqrt(E * (1 - NU) / (RHO * (1 + NU) * (1 - 2 * NU)))  # m/s, dilatational
V = 1.0  # m/s, the platen's speed after the ramp
T_RAMP = 60e-6  # s: 22 transit times H0/c
T_END = 400e-6  # s: 8 % reduction
MATERIAL = FiniteJ2(E=E, nu=NU, density=RHO, yield_stress=SIGMA_Y, hardening=0.0)


@pytest.fixture(scope="module")
def tmp(tmp_path_factory):
    path = tmp_path_factory.mktemp("upset") if COMM.rank == 0 else None
    return COMM.bcast(path)


def _run(tmp, mu: float):
    """The run's summary, history and the largest |lambda_t| - mu lambda_n over the active
    pairs of both faces and every step (N)."""
    out = str(tmp / f"mu{mu}")
    settings = Settings(out=out, quiet=True, plots=False, fields=False, timers=False,
                        history_every=1, energy_every=10)
    sim = scenes.upsetting(settings, MATERIAL, R0, H0, 4, 4, friction=mu, speed=V,
                           t_ramp=T_RAMP, t_end=T_END)
    excess = [-np.inf]
    for c in sim.contacts:
        if c.friction is None:
            continue
        step = c.friction.step

        def checked(c=c, step=step):
            w = step()
            on = c.active & (c.force > 0.0)
            if on.any():  # (the set's rows are replicated: every rank checks all)
                excess[0] = max(excess[0], float(
                    (np.abs(c.friction.lam[on]) - mu * c.force[on]).max()))
            return w
        # the pass as a call of its own (bit for bit the folded one: test_friction_fused)
        c.friction.step, c.friction.folds = checked, False
    s = sim.run()
    COMM.Barrier()
    return s, read_history(out), excess[0]


def _ledger_closes(s) -> None:
    # the ledger's residual over its largest term, within each step's roundings
    assert s["status"] == "completed"
    assert s["energy_balance_error_rel"] <= ledger(s["n_steps"], s["n_dofs"])


def test_frictionless_pressure_is_the_yield_stress_over_j(tmp):
    s, h, _ = _run(tmp, 0.0)
    _ledger_closes(s)
    K = E / (3 * (1 - 2 * NU))  # Pa, bulk modulus
    J = math.exp(-SIGMA_Y / (3 * K))  # the volume ratio at tau_zz = -sigma_y
    # flowing: from 2 T_RAMP (the yield strain, 1 %, is reached at about 80 us)
    flowing = h["time"] >= 2 * T_RAMP + 30e-6
    p = np.abs(h["c0_platen_force"][flowing]) / (math.pi * h["r_top"][flowing] ** 2)  # Pa
    mean, spread = p.mean(), np.ptp(p)
    if COMM.rank == 0:
        print(f"\nmu = 0, {flowing.sum()} steps flowing: F / (pi r_top^2) = {mean / SIGMA_Y:.5f} "
              f"sigma_y, sigma_y / J = {1 / J:.5f} sigma_y, ringing (max - min) "
              f"{spread / SIGMA_Y:.4f} sigma_y, rho c V = {RHO * C * V / SIGMA_Y:.4f} sigma_y; "
              f"ledger {s['energy_balance_error_rel']:.2g} of its largest term (bound "
              f"{ledger(s['n_steps'], s['n_dofs']):.2g}), the crosshead's work "
              f"{s['energy']['external_work']:.4g} J")
    assert abs(mean - SIGMA_Y / J) <= 0.5 * spread  # inside the ringing's envelope
    assert spread <= RHO * C * V  # the ringing within the impedance pressure
    # the current area is J pi R_eq^2 (R_eq^2 = R0^2 H0 / H, the volume J V0), so the
    # force over pi R_eq^2 is sigma_y itself
    H = H0 + h["c0_platen_u"][flowing]  # m (u_platen < 0)
    p_eq = np.abs(h["c0_platen_force"][flowing]) / (math.pi * R0 ** 2 * H0 / H)  # Pa
    assert abs(p_eq.mean() - SIGMA_Y) <= 0.5 * np.ptp(p_eq)


def test_friction_keeps_every_pair_in_the_cone(tmp):
    mu = 0.1
    s, h, excess = _run(tmp, mu)
    _ledger_closes(s)
    peak = max(np.abs(h["c0_platen_force"]).max(), np.abs(h["c1_wall_force"]).max())  # N
    if COMM.rank == 0:
        print(f"\nmu = {mu}: max over pairs and steps of |lambda_t| - mu lambda_n = {excess:.3g} N "
              f"(peak platen force {peak:.4g} N), slip work {s['friction'][0]['slip_work']:.4g} J, "
              f"ledger {s['energy_balance_error_rel']:.2g} (bound "
              f"{ledger(s['n_steps'], s['n_dofs']):.2g})")
    # |lambda_t| <= mu lambda_n at every active pair and step, to the rounding of the
    # product mu lambda_n (the slip force is the cone's own value: one rounding)
    assert excess <= 4 * np.finfo(float).eps * mu * peak
    assert excess > -np.inf  # pairs were active with friction
    # friction holds the faces back: the side barrels
    assert h["r_mid"][-1] > h["r_top"][-1]
