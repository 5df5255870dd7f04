"""The discrete energy ledger and the update form.

Oracles: the exact conservation law of the modified Euler scheme,
E_n = 1/2 v^n' M v^{n+1} + 1/2 u^n' K u^n, with the matching work of the
loads (to the round-off of a ledger, tests/roundoff.py); and the textbook (u, v) form
of paper eq. (1), run independently with SciPy on the same K and M, which the PETSc
update must reproduce (other expressions at every step: within the steps x the spread
of the textbook run under a one-ulp change of its initial velocity).
"""
import numpy as np
import pytest
import scipy.sparse as sp
from mpi4py import MPI

from impact_fenics import loads, meshing, scenes
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.integrator import Integrator
from impact_fenics.materials import LinearElastic
from impact_fenics.simulation import Settings
from roundoff import EPS, assert_within_spread, ledger, rounding


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


def test_a_run_from_a_displaced_state_balances_from_its_first_row():
    """An integrator given a displaced state u^0 (a random one, as the benchmark's; zero on
    the fixed dofs): E_0 holds the linear bodies' 1/2 (u^0)' K u^{-1}, u^{-1} = u^0 - h v^0,
    the telescoped work's first term (one_loop.md 4.7), so the balance closes to the
    ledger's round-off from the first row; without that term it is off by the stored
    energy of u^0, all of E_0's order."""
    sim = scenes.elastic_bar(Settings(cfl=0.9, n_steps=200, output_every=20, quiet=True),
                             h=0.02, length=0.5, nu=0.3, peak=0.0, clamp_far_end=True)
    integ = sim.integrator
    rng = np.random.default_rng(11 + 7919 * sim.comm.rank)
    u0 = 1e-6 * rng.standard_normal(integ.u_owned.size)
    v0 = 1e-3 * rng.standard_normal(integ.u_owned.size)
    fixed = integ.fixed[integ.fixed < u0.size]
    u0[fixed] = 0.0
    v0[fixed] = 0.0
    integ.set_initial(u0, v0)
    summary = sim.run()
    e = sim.energy.data()
    assert summary["status"] == "completed"
    stored = summary["energy_initial"] - 0.5 * sim.comm.allreduce(
        float(np.dot(integ.mass * v0, v0)))
    assert stored > 0.5 * summary["energy_initial"]  # the displaced state holds most of E_0
    assert np.all(np.abs(e["balance_error_rel"]) <= ledger(200, summary["n_dofs"]))


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


# ------------------------------------------------------------------ the kinetic identity

class _Steps:
    """The states of each step of a run's Python loop, recorded around the integrator's
    predict and advance (the test's instrument: it copies, it changes nothing): u^n,
    v^{n-1/2}, K u^n (a MatMult, independent of the run's prediction), the prediction v~,
    v^{n+1/2}, u^{n+1} and the moving rigid bodies' v^{n-1/2}, v^{n+1/2}."""

    def __init__(self, sim):
        integ = sim.integrator
        rigid = [c.rigid for c in sim.contacts if c.moving_rigid is not None]
        self.rigid_mass = np.array([b.mass for b in rigid])
        self.rows = []
        predict, advance, ku = integ.predict, integ.advance, integ.u_vec.duplicate()

        def predict_() -> None:
            integ.K.mult(integ.u_vec, ku)
            self.rows.append({"u": integ.u_owned.copy(), "v": integ.v_owned.copy(),
                              "ku": ku.array.copy(), "V": np.array([b.v for b in rigid])})
            predict()
            self.rows[-1]["v_pred"] = integ.v_owned.copy()

        def advance_() -> None:
            advance()
            row = self.rows[-1]
            row["v_next"], row["u_next"] = integ.v_owned.copy(), integ.u_owned.copy()
            row["V_next"] = np.array([b.v for b in rigid])

        integ.predictor = lambda: predict_
        integ.advance = advance_


def _old_ledger(sim, steps: _Steps):
    """Per step n, from the recorded states only: the previous form of the ledger,
    E_n^old = 1/2 v^{n-1/2} M v^{n+1/2} + 1/2 u^n K u^n (+ 1/2 m V^{n-1/2} V^{n+1/2} of a
    rigid body), its work W_n^old = sum over m = 1..n of 1/2 h v^{m-1/2} . (F^{m-1} + F^m)
    with a jump's 1/2 j^m . K (u^{m-1} + u^m) (j^m = u^m - u^{m-1} - h v^{m-1/2}), and the
    boundary term 1/2 h v^{n+1/2} . F^n, where F^n is every applied and contact force of
    the step: M (v^{n+1/2} - v~) / h on the dofs (no load acts) and m (V^{n+1/2} -
    V^{n-1/2}) / h on a rigid body (its external force and the contact's). Also the terms'
    magnitudes, for the round-off bound. Sums over the ranks."""
    comm = sim.comm
    m, h, M = sim.integrator.mass, sim.settings.dt, steps.rigid_mass
    E_old, W_old, boundary, first = [], [], [], None
    work, prev = 0.0, None
    for r in steps.rows:
        F = m * (r["v_next"] - r["v_pred"]) / h
        FV = M * (r["V_next"] - r["V"]) / h
        local = np.array([
            0.5 * np.dot(m * r["v"], r["v_next"]) + 0.5 * np.dot(r["u"], r["ku"]),
            0.5 * h * np.dot(r["v_next"], F),
            0.5 * h * np.dot(r["v"], F),
            0.0])
        if prev is not None:
            jump = r["u"] - prev["u"] - h * r["v"]
            local[3] = (0.5 * h * np.dot(r["v"], prev["F"] + F)
                        + 0.5 * np.dot(jump, prev["ku"] + r["ku"]))
        total = comm.allreduce(local)
        total[0] += float(np.sum(0.5 * M * r["V"] * r["V_next"]))
        total[1] += float(np.sum(0.5 * h * r["V_next"] * FV))
        total[2] += float(np.sum(0.5 * h * r["V"] * FV))
        if prev is not None:
            total[3] += float(np.sum(0.5 * h * r["V"] * (prev["FV"] + FV)))
        work += total[3]
        E_old.append(total[0])
        W_old.append(work)
        boundary.append(total[1])
        if first is None:
            first = total[2]  # 1/2 h v^0 . F^0
        prev = {"u": r["u"], "ku": r["ku"], "F": F, "FV": FV}
    return np.array(E_old), np.array(W_old), np.array(boundary), first


def _bars(method):
    return scenes.bar_impact(Settings(cfl=0.9, n_steps=150, energy_every=1, output_every=150,
                                      quiet=True, compiled_steps=False),
                             scenes.make_method(method), h=0.04, striker_length=0.4,
                             target_length=0.4)


def _punch(method):
    from impact_fenics import meshing

    tm = meshing.punch_block(width=1.5, depth=0.5, h_surface=0.05, grading=1.0, h_max=0.25,
                             breaks=((1.0, 20),))
    return scenes.punch_indentation(Settings(cfl=0.9, n_steps=150, energy_every=1,
                                             output_every=150, quiet=True,
                                             compiled_steps=False),
                                    scenes.make_method(method), radius=1.0, tmesh=tm)


@pytest.mark.parametrize("scene", ["bars", "punch"])
@pytest.mark.parametrize("method", ["film", "dme", "penalty"])
def test_new_columns_are_the_old_ledger_plus_its_boundary_terms(scene, method):
    """The ledger books every force by the kinetic identity of the half-step scheme. Its
    columns and the previous form's (E_n^old, W_n^old, computed here from the recorded
    states, see _old_ledger) differ by exact boundary terms:
    (T + Phi)_n = E_n^old + 1/2 h v^{n+1/2} . F^n (kinetic + strain),
    W_n = W_n^old + 1/2 h v^{n+1/2} . F^n + 1/2 h v^0 . F^0 (external + contact work), and
    the reference E_0 = 1/2 |v^0|^2_M = E_0^old - 1/2 h v^0 . F^0. Both sides are sums of
    the same exact quantities in other orders: within 10 EPS x the terms summed (per dof:
    the kinetic, strain, boundary and old energy sums, six; per step and contact slot: the
    two work bookings, two) x the scale of the energies."""
    sim = _bars(method) if scene == "bars" else _punch(method)
    steps = _Steps(sim)
    summary = sim.run()
    assert summary["status"].startswith("completed")
    E_old, W_old, boundary, first = _old_ledger(sim, steps)
    e = sim.energy.data()
    assert e["step"].tolist() == list(range(len(steps.rows)))  # a row after every step
    new_E = e["kinetic"] + e["strain"]
    new_W = e["external_work"] + e["contact_work"]
    # the terms are not nil (on node pairs that a step leaves at one velocity the forces
    # cancel in 1/2 h v^{n+1/2} . F^n, but not in the first step's 1/2 h v^0 . F^0)
    assert abs(first) + np.abs(boundary).max() > 1e-3 * np.abs(E_old).max()
    scale = max(np.abs(E_old).max(), np.abs(W_old).max(), np.abs(new_E).max(),
                np.abs(new_W).max(), np.abs(e["kinetic"]).max(), np.abs(e["strain"]).max())
    n_dofs, n_slots = summary["n_dofs"], sum(c.n_slots for c in sim.contacts)
    n = np.arange(1, len(E_old) + 1)
    bound = rounding(10 * (6 * n_dofs + 2 * n * (n_slots + 1)), scale)
    print(scene, method, "E:", np.abs(new_E - (E_old + boundary)).max(), "W:",
          np.abs(new_W - (W_old + boundary + first)).max(), "bound", bound.min(), "-",
          bound.max(), "1/2 h v0.F0", first, "scale", scale)
    assert np.all(np.abs(new_E - (E_old + boundary)) <= bound)
    assert np.all(np.abs(new_W - (W_old + boundary + first)) <= bound)
    assert abs(sim.ledger.E0 - (E_old[0] - first)) <= bound[0]
    # and the ledger closes on them from the first row
    assert np.abs(e["balance_error_rel"]).max() <= ledger(len(n), n_dofs)


def _bonded_with_a_loaded_face():
    """A linear elastic disc (z below 5 mm) bonded to a J2 disc (above) on one triangle mesh
    (their interface nodes shared), 4 x 10 mm, the face z = 0 in the group ``loaded_end``,
    the face z = 10 mm in ``held``."""
    from dolfinx import mesh as dmesh

    from impact_fenics.materials.j2 import J2
    from impact_fenics.meshing import TaggedMesh
    from two_halves import two_halves

    comm = MPI.COMM_WORLD
    tm = two_halves(comm, (0.0, 0.0), (4e-3, 10e-3), 4, 10, False, ("anvil", "plate"))
    mesh = tm.mesh
    mesh.topology.create_connectivity(1, 2)
    face = dmesh.locate_entities_boundary(mesh, 1, lambda p: np.abs(p[1]) <= 1e-12)
    top = dmesh.locate_entities_boundary(mesh, 1, lambda p: np.abs(p[1] - 10e-3) <= 1e-12)
    order = np.argsort(np.concatenate([face, top]))
    facets = dmesh.meshtags(mesh, 1, np.concatenate([face, top]).astype(np.int32)[order],
                            np.repeat(np.int32([1, 2]), [face.size, top.size])[order])
    tm = TaggedMesh(mesh, tm.cell_tags, facets, tm.cell_names, {"loaded_end": 1, "held": 2})
    j2 = J2(E=200e9, nu=0.3, density=7850.0, yield_stress=200e6, hardening=5e9)
    return DeformableModel(tm, [Body("anvil", LinearElastic(nu=0.3)), Body("plate", j2)])


def test_the_ledger_closes_across_a_bonded_linear_j2_interface_under_a_load():
    """The balance to round-off (roundoff.ledger) on a loaded linear body bonded to a J2 one
    that yields: the nodes of their interface take the linear force's and the J2 force's
    increments, the loaded face the load's; the work of the load is booked by the kinetic
    identity, the internal forces' by the stored energy and its boundary term, and the
    rows close from the first one (E_0 is the initial state: at rest, 0). The plate's far
    face is held in z, so the waves ring in the bodies and nothing drifts (a drift would
    round K u on a growing |u|: see roundoff.ledger)."""
    model = _bonded_with_a_loaded_face()
    pulse = loads.Trapezoid(peak=800e6, t_rise=1e-6, t_fall=4e-6, t_end=5e-6)
    load = loads.SurfaceLoad(model, "loaded_end", pulse)
    sim = scenes.Simulation(model, Settings(cfl=0.5, n_steps=2000, output_every=50,
                                            quiet=True),
                            fixed=[model.axis_dofs(), model.facet_dofs("held", 1)],
                            loads=[load])
    summary = sim.run()
    e = sim.energy.data()
    assert summary["status"].startswith("completed")
    assert sim.ledger.E0 == 0.0
    assert e["external_work"][-1] > 0.0
    assert e["plastic_work"][-1] > 0.01 * e["external_work"][-1]  # the plate yielded
    assert np.abs(e["balance_error_rel"]).max() <= ledger(2000, summary["n_dofs"])
    # the deformation work of the J2 plate, by the kinetic identity: its stored energy with
    # its share of the boundary term, and its plastic work (psi_e^0 = 0 at rest)
    print("balance", np.abs(e["balance_error_rel"]).max(), "bound",
          ledger(2000, summary["n_dofs"]), "plastic share",
          e["plastic_work"][-1] / e["external_work"][-1])
