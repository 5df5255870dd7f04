"""The rigid wall's three methods against the 1D impact of an elastic bar.

A bar of length L with nu = 0 at a small speed v0 (strain v0 / c0 = 2e-4: the
neo-Hookean bar is linear to that order) onto a rigid wall: the continuum
solution is the 1D one (nu = 0 admits exact plane waves): the bar
stays in contact for 2 L / c0 (c0 = sqrt(E / rho)) and leaves with +v0.
The lumped chain reaches this only as h -> 0: the layer of nodes on the face
(mass rho pi a^2 h / 2, exactly, the row sum of Q1's consistent mass) loses its
kinetic energy K0 h / (2 L) at the impact (FILM, DME; a stiff spring about as
much), about as much again at the release, and the chain's dispersion leaves
vibration energy behind. So the contact duration and the rebound velocity
carry errors of order h / L: the tests bound them by h / L and 1.5 h / L and
demand that they shrink from h = a/2 to h = a/4.

Exact statements, to round-off: the activation loss of the first step is
1/2 m_face v0^2 = K0 h / (2 L); the penalty wall with beta = 1 (``scaled``) is FILM;
with any penalty the kinetic identity K + W_int + L_wall + E_spring = K0 holds at
every step (the spring energy 1/2 p g^2 is stored, then returned when the spring
releases: zero after the bar has left).
"""
import math

import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics.finite_run import FiniteRun, FiniteSettings, quad_bar
from impact_fenics.materials.neo_hookean import NeoHookean

E, RHO, V0, A, L = 200e9, 7850.0, 1.0, 0.01, 0.1  # Pa, kg/m^3, m/s, m, m
C0 = math.sqrt(E / RHO)
BAR = NeoHookean(E=E, nu=0.0, density=RHO)


def impact(comm, n_r: int, method: str, penalty="scaled", beta: float = 1.0):
    """The bar (n_r x 10 n_r square cells) from contact at t = 0 to 2.6 L / c0."""
    mesh = quad_bar(comm, A, L, n_r, 10 * n_r)
    run = FiniteRun(mesh, BAR, FiniteSettings(t_end=2.6 * L / C0, history_every=1),
                    velocity=(0.0, -V0), wall=method, penalty=penalty, penalty_beta=beta)
    s = run.run()
    h = run.history
    on = np.flatnonzero(h["n_active"] > 0)
    # a row holds the state before its step: row 1 is after the first step's correction
    assert on[0] == 1 and on[-1] + 1 < h["time"].size  # in contact from the start, then free
    duration = h["time"][on[-1] + 1] - h["time"][on[0]]
    return s, h, duration


@pytest.mark.parametrize("method, beta", [("film", 1.0), ("penalty", 0.5)],
                         ids=["film", "penalty_beta_0.5"])
def test_elastic_bar_rebounds_as_in_1d(comm, method, beta):
    errors = []
    for n_r in (2, 4):
        s, h, duration = impact(comm, n_r, method, beta=beta)
        h_over_l = (A / n_r) / L
        err_t = abs(duration / (2 * L / C0) - 1.0)
        err_v = abs(h["velocity_z"][-1] / V0 - 1.0)
        assert err_t <= h_over_l and err_v <= 1.5 * h_over_l, (n_r, err_t, err_v)
        assert abs(s["kinetic_identity_error"]) < 1e-13
        assert h["penalty_energy"][-1] == 0.0  # every spring released
        errors.append((err_t, err_v))
    assert errors[1][0] < errors[0][0] and errors[1][1] < errors[0][1]


def test_first_activation_loss_is_the_face_layers_kinetic_energy(comm):
    """At t = 0 the face nodes (mass rho pi a^2 h / 2) stop: FILM books 1/2 m v0^2."""
    n_r = 2
    s, h, _ = impact(comm, n_r, "film")
    K0 = 0.5 * RHO * math.pi * A * A * L * V0 ** 2
    assert s["initial_kinetic"] == pytest.approx(K0, rel=1e-12)
    assert h["activation_loss"][1] == pytest.approx(K0 * (A / n_r) / (2 * L), rel=1e-12)


def test_scaled_penalty_at_beta_one_is_film(comm):
    a, ha, _ = impact(comm, 2, "film")
    b, hb, _ = impact(comm, 2, "penalty", beta=1.0)
    assert a["n_steps"] == b["n_steps"]
    for key in ("velocity_z", "length", "kinetic", "wall_force"):
        scale = np.abs(ha[key]).max()
        assert np.abs(ha[key] - hb[key]).max() <= 1e-12 * scale, key
    # the energy: FILM's loss is the penalty's loss plus what its spring holds (none after)
    assert b["activation_loss"] + b["penalty_energy"] == pytest.approx(a["activation_loss"],
                                                                       rel=1e-10)


def test_penalty_stiffness_stores_and_returns_its_energy(comm):
    """A stiffness in N/m (beta = 0.8 at the lightest face node at the start): while the
    springs are loaded they hold energy (the kinetic identity counts it, to round-off);
    after the release they hold none and the run's loss is all that is missing."""
    run0 = FiniteRun(quad_bar(comm, A, L, 2, 20), BAR, FiniteSettings(), wall="penalty")
    m_min = comm.allreduce(float(run0.wall.mass.min(initial=np.inf)), op=MPI.MIN)
    dt = 0.5 * run0.dt_limit()
    p = 0.8 * m_min / dt ** 2  # N/m
    s, h, _ = impact(comm, 2, "penalty", penalty=p)
    K0 = s["initial_kinetic"]
    assert s["wall"]["beta_max"] == pytest.approx(0.8, rel=1e-12)
    assert np.abs(h["balance_error"]).max() < 1e-13 * K0
    assert h["penalty_energy"].max() > 1e-3 * K0  # stored while loaded
    assert h["penalty_energy"][-1] == 0.0
    total = h["kinetic"] + h["internal_work"] + h["activation_loss"] + h["penalty_energy"]
    assert np.abs(total - K0).max() < 1e-13 * K0


def test_penalty_above_the_bound_is_refused(comm):
    from impact_fenics.errors import InputError

    run = FiniteRun(quad_bar(comm, A, L, 2, 20), BAR, FiniteSettings(t_end=1e-6),
                    velocity=(0.0, -V0), wall="penalty", penalty=1e15)
    with pytest.raises(InputError, match=r"beta_max = p dt\^2 / m = .* above the stable bound 4/3"):
        run.run()
