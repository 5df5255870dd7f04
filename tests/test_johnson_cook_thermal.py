"""Johnson-Cook's thermal factor 1 - T*^m kept in the point state against the previous path,
which computed it from the stored temperature at every point and step.

The temperature changes only where a point flows, and there the update stores
thermal_factor(params, T) of the new T, by the expression the previous path evaluated from
the same T at the next step: so the kept factor is that value bit for bit, and the runs are
equal bit for bit (no tolerance: the same operations on the same operands). The previous
path is kept here as the reference: the update with the factor recomputed from the stored
temperature before it runs, as the previous code did at the start of its update.
"""
import math
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI
from numba import njit

from finite_body import bar_simulation
from impact_fenics.materials.johnson_cook import (TEMPERATURE, THERMAL, JohnsonCook,
                                                  thermal_factor, update)
from impact_fenics.quad_meshes import quad_bar


@njit(cache=True, error_model="numpy")
def recomputing_update(F, state, params, dt, tau, work) -> float:
    """The previous path: 1 - T*^m from the stored T at every point and step."""
    state[THERMAL] = thermal_factor(params, state[TEMPERATURE])
    return update(F, state, params, dt, tau, work)


@dataclass(frozen=True)
class RecomputingJohnsonCook(JohnsonCook):
    update = staticmethod(recomputing_update)


def test_the_state_keeps_the_factor_of_its_temperature():
    """Along a straining path (loading, unloading, reloading: the update's own returns),
    the state's factor is thermal_factor of its T bit for bit after every step, also at the
    steps where a heated point stays elastic (the steps that read the kept factor)."""
    m = JohnsonCook(m=0.8)
    p = m.params()
    state = m.initial_state().copy()
    assert state[THERMAL] == thermal_factor(p, state[TEMPERATURE])  # 1 at T_room
    tau, work = np.zeros(4), np.zeros(16)
    flowed = heated_elastic = 0
    for k in range(1, 200):
        e = 0.004 * math.sin(0.05 * k) + 1e-4 * k
        before = state.copy()
        m.update(np.array([math.exp(-e / 2), 0.0, 0.0, math.exp(e), math.exp(-e / 2)]), state, p,
                 1e-8, tau, work)
        if state[0] > before[0]:
            flowed += 1
        elif before[TEMPERATURE] > m.t_room:
            heated_elastic += 1
            assert state[TEMPERATURE] == before[TEMPERATURE]
        assert state[THERMAL] == thermal_factor(p, state[TEMPERATURE])
    assert flowed > 20 and heated_elastic > 20 and state[THERMAL] < 1.0


def _bar(comm, material):
    """The Johnson-Cook copper bar onto the wall of tests/test_finite_strain.py (coarse,
    10 us, DME): points heat at the impact face, and unload elastically behind it."""
    return bar_simulation(quad_bar(comm, 3.2e-3, 32.4e-3, 2, 20), material, 10e-6,
                          (0.0, -227.0), "dme")


def test_bar_matches_the_recomputing_path_bit_for_bit(comm):
    """The whole run with the kept factor against the previous path: u, v, every point's
    state (eps_bar_p, C_p^-1, T, B eps_bar_p^n, the factor) and Kirchhoff stress equal bit
    for bit, and the same steps; the kept factor is thermal_factor of the stored T."""
    runs = []
    for material in (JohnsonCook(), RecomputingJohnsonCook()):
        sim = _bar(comm, material)
        s = sim.run()
        force = sim.integrator.finite[0]
        runs.append((s["n_steps"], sim.integrator.u_owned.copy(), sim.integrator.v_owned.copy(),
                     force.state.copy(), force.tau.copy()))
    (n_new, u_new, v_new, state_new, tau_new), (n_old, u_old, v_old, state_old, tau_old) = runs
    assert n_new == n_old
    np.testing.assert_array_equal(u_new, u_old)
    np.testing.assert_array_equal(v_new, v_old)
    np.testing.assert_array_equal(state_new, state_old)
    np.testing.assert_array_equal(tau_new, tau_old)
    p = JohnsonCook().params()
    temp = state_new[..., TEMPERATURE]
    kept = np.array([thermal_factor(p, t) for t in temp.ravel()]).reshape(temp.shape)
    np.testing.assert_array_equal(state_new[..., THERMAL], kept)
    hot = comm.allreduce(int((temp > JohnsonCook().t_room + 20.0).sum()), op=MPI.SUM)
    assert hot > 0  # the run heated points by tens of kelvin: the factor was kept below 1
