"""The discrete energy ledger and the update form.

Oracles: the exact conservation law of the modified Euler scheme,
E_n = 1/2 v^n' M v^{n+1} + 1/2 u^n' K u^n, with the matching work of the
loads (to the round-off of a ledger, tests/roundoff.py); and the textbook (u, v) form
of paper eq. (1), run independently with SciPy on the same K and M, which the PETSc
update must reproduce (other expressions at every step: within the steps x the spread
of the textbook run under a one-ulp change of its initial velocity).
"""
import numpy as np
import scipy.sparse as sp

from impact_fenics import loads, meshing, scenes
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.integrator import Integrator
from impact_fenics.materials import LinearElastic
from impact_fenics.simulation import Settings
from roundoff import EPS, assert_within_spread, ledger


def test_petsc_update_equals_textbook_modified_euler():
    model = DeformableModel(meshing.bar(radius=0.05, length=0.3, h=0.01, structured=False),
                            [Body("bar", LinearElastic(nu=0.3))])
    pulse = loads.Trapezoid(peak=50e6, t_rise=1e-5, t_fall=3e-5, t_end=4e-5)
    load = loads.SurfaceLoad(model, "loaded_end", pulse)
    fixed = model.axis_dofs()
    dt = 5e-7
    integ = Integrator(model, dt, fixed, [load])
    rng = np.random.default_rng(1 + model.comm.rank)
    v0 = rng.standard_normal(model.n_owned)
    integ.set_initial(None, v0)
    # the (u, v) form on the local rows: gather K, M, f once to rank-local SciPy
    ip, ix, val = integ.K.getValuesCSR()
    K = sp.csr_matrix((val, ix, ip), shape=(model.n_owned, model.n_global))
    free = np.ones(model.n_owned)
    free[fixed] = 0.0
    m = integ.mass
    f0 = np.zeros(model.n_owned)
    f0[load.dofs] = load.force

    def textbook(v_start):
        u = np.zeros(model.n_owned)
        v = v_start * free
        for n in range(200):
            u_all = np.concatenate(model.comm.allgather(u))
            a = (pulse(n * dt) * f0 - K @ u_all) / m * free
            v = v + dt * a
            u = u + dt * v
        return u

    for n in range(200):
        integ.predict()
        integ.advance()
    got = np.empty(model.n_owned)
    integ.displacement(got)
    gather = lambda x: np.concatenate(model.comm.allgather(x))  # noqa: E731
    u, u_ulp = textbook(v0), textbook(np.nextafter(v0, np.inf))
    assert_within_spread(gather(got), gather(u), gather(u_ulp), 200, "u")


def test_energy_balance_holds_to_round_off_over_1e4_steps():
    # A clamped-free bar rings after the pulse (a free bar would drift away, and
    # K u of a large rigid drift is round-off of |K| |u|: see docs/results.md).
    # dt = 0.9 of the converged limit: above the conservative element bound, so forced.
    bar = dict(h=0.02, length=0.5, nu=0.3, peak=50e6, clamp_far_end=True)
    probe = scenes.elastic_bar(Settings(dt=1e-8, n_steps=1, force_dt=True, converged_dt=True,
                                        quiet=True), **bar)
    sim = scenes.elastic_bar(Settings(dt=0.9 * probe.dt_converged, n_steps=10_000,
                                      output_every=100, force_dt=True, quiet=True), **bar)
    summary = sim.run()
    e = sim.energy.data()
    assert summary["status"] == "completed"
    assert e["external_work"][-1] > 0  # the pulse did work; the energy then rings on
    assert e["strain"][-1] > 0.1 * e["total"][-1]
    assert np.all(e["balance_error_rel"] <= ledger(10_000, summary["n_dofs"]))
    # no drift: round-off of each step (a 14-term row product, a few vector
    # operations: ~16 eps relative), of either sign, adds up as a random walk,
    # sqrt(n) 16 eps; a drift (a term booked with the wrong step) grows as n
    late = e["balance_error_rel"][e["step"] >= 9_000]
    assert late.max() <= np.sqrt(10_000) * 16 * EPS


def test_loads_do_not_move_fixed_dofs():
    """A traction with a radial part on the loaded end (which touches the axis) and a
    lateral face held in z: u_r = 0 on the axis and u_z = 0 on the lateral face hold
    exactly, and the ledger still balances."""
    model = DeformableModel(meshing.bar(radius=0.05, length=0.3, h=0.01),
                            [Body("bar", LinearElastic(nu=0.3))])
    pulse = loads.Trapezoid(peak=50e6, t_rise=1e-5, t_fall=3e-5, t_end=4e-5)
    load = loads.SurfaceLoad(model, "loaded_end", pulse, traction=(1.0, 1.0))
    lateral_z = model.facet_dofs("lateral", 1)
    axis_r = model.axis_dofs()
    assert model.comm.allreduce(int(np.intersect1d(load.dofs, axis_r).size)) > 0
    sim = scenes.Simulation(model, Settings(dt=5e-7, n_steps=200, output_every=20, quiet=True),
                            fixed=[lateral_z], loads=[load])
    summary = sim.run()
    u = np.empty(model.n_owned)
    sim.integrator.displacement(u)
    assert np.all(u[axis_r] == 0.0) and np.all(u[lateral_z] == 0.0)
    assert summary["energy_balance_error_rel"] <= ledger(200, summary["n_dofs"])
