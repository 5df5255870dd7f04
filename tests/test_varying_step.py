"""The small-strain driver under a varying step: the ledger's bookings of one_loop.md 4.7.

With h_{n+1/2} the step from t^n to t^{n+1} and h_n = 1/2 (h_{n-1/2} + h_{n+1/2}), every
force's share of the kinetic identity is 1/2 (v^{n-1/2} + v^{n+1/2}) . h_n f^n. A
step policy that is not the constant one (here stepping.StepSequence) makes the linear
bodies take the per-step pass, whose booking the correction after contact makes exact on
the dofs that take more than one increment (contact slots, loaded dofs, nodes shared by
two bodies), and the split of the internal work into stored energy, its boundary term
and dissipation leaves out, at each change of step,

    1/4 (h_{n+1/2} - h_{n-1/2}) (v^{n-1/2} - v^{n+1/2}) . f_int^n     (the work_gap column).

Oracles:

* The kinetic identity: E_n - E_0 - W_n = 0 to round-off (roundoff.ledger) for any
  sequence of steps, on the bars in contact (each method; the contact slots are
  multiply-touched dofs) and on a loaded linear body bonded to a yielding J2 one.
* work_gap against its formula, summed here from the recorded states (u^n, v^{n-1/2},
  v^{n+1/2}, and K u^n by a MatMult of the recorded u^n, independent of the run's
  pass and of its booking): equal to round-off; and between two changes of step the
  column does not move beyond round-off (the split closes there).
* Steps that do not change, through the same varying path: work_gap 0 to round-off.
* A constant policy keeps today's path: the existing ledger tests (test_energy,
  test_step_block, test_half_step) run unchanged.
"""
import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics import loads, meshing, scenes
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.contact.pairing import pair_surfaces
from impact_fenics.errors import InputError
from impact_fenics.materials import LinearElastic
from impact_fenics.simulation import Settings, Simulation
from impact_fenics.stability import critical_dt, element_omega_bounds, ghosted_dofs
from impact_fenics.stepping import StepSequence
from roundoff import ledger, rounding
from test_energy import _bonded_with_a_loaded_face

COMM = MPI.COMM_WORLD
N_STEPS = 150
# the step's factors of the stable limit, each held for 10 steps: it falls and rises
FACTORS = (0.9, 0.6, 0.75, 0.45, 0.8, 0.55, 0.85, 0.5, 0.7, 0.9, 0.65, 0.4, 0.6, 0.8, 0.9)


def _steps(limit: float, factors=FACTORS, hold: int = 10) -> list[float]:
    return [f * limit for f in factors for _ in range(hold)]


def _limit(model: DeformableModel, fixed=()) -> float:
    local = np.unique(np.concatenate([model.axis_dofs(owned=False)] + list(fixed)))
    return critical_dt(max(element_omega_bounds(model, local).values()))


def _bars(method: str, steps=None) -> Simulation:
    """The coaxial steel bars of scenes.bar_impact (striker at 5 m/s) under given steps."""
    tm = meshing.coaxial_bars(radius=0.1, striker_length=0.4, target_length=0.4, h=0.04)
    steel = LinearElastic(nu=0.3)
    model = DeformableModel(tm, [Body("striker", steel), Body("target", steel)])
    policy = StepSequence(steps if steps is not None else _steps(_limit(model)))
    sim = Simulation(model, Settings(energy_every=1, output_every=N_STEPS, quiet=True),
                     initial_velocity={"striker": (0.0, 5.0)}, policy=policy)
    sim.add_contact(pair_surfaces(model, "striker_contact", "target_contact"),
                    scenes.make_method(method))
    return sim


class _Record:
    """Per step, around the integrator's predict and advance (it copies, changes
    nothing): h_{n-1/2}, h_{n+1/2}, u^n, v^{n-1/2}, K u^n (a MatMult here) and v^{n+1/2};
    a small-strain body's f_int^n (its force array after the pass)."""

    def __init__(self, sim: Simulation):
        integ = sim.integrator
        self.rows = []
        predict, advance, ku = integ.predict, integ.advance, integ.u_vec.duplicate()
        K = integ.linear.K

        def predict_() -> None:
            K.mult(integ.u_vec, ku)
            row = {"u": integ.u_owned.copy(), "v": integ.v_owned.copy(),
                   "ku": ku.array.copy(), "h_prev": integ.step.h_prev}
            predict()
            row["h"] = integ.step.h
            row["f_small"] = sum(f.f_owned.copy() for f in integ.nonlinear)
            self.rows.append(row)

        def advance_() -> None:
            self.rows[-1]["v_next"] = integ.v_owned.copy()
            advance()

        integ.predictor = lambda: predict_
        integ.advance = advance_

    def gap(self) -> tuple[np.ndarray, np.ndarray]:
        """Per step, the sum of 1/4 (h_{m+1/2} - h_{m-1/2}) (v^{m-1/2} - v^{m+1/2}) . f_int^m
        over m <= n (J, summed over the ranks), and the sum of the terms' magnitudes
        |1/4 dh| |v^- - v^+| |f| (J), the scale of its round-off."""
        terms, sizes = [], []
        for r in self.rows:
            dh = 0.0 if r["h_prev"] is None else r["h"] - r["h_prev"]
            f = r["ku"] + r["f_small"]
            dv = r["v"] - r["v_next"]
            local = np.array([0.25 * dh * np.dot(dv, f),
                              abs(0.25 * dh) * np.dot(np.abs(dv), np.abs(f))])
            t = COMM.allreduce(local)
            terms.append(t[0])
            sizes.append(t[1])
        return np.cumsum(terms), np.cumsum(sizes)


def _scale(e) -> float:
    return max(np.abs(e[k]).max() for k in ("kinetic", "strain", "total", "external_work",
                                             "contact_work", "work_gap"))


@pytest.mark.parametrize("method", ["film", "dme", "penalty"])
def test_the_bars_keep_the_kinetic_identity_under_varying_steps(method):
    """The ledger closes from its first row, and work_gap is its formula from the states."""
    sim = _bars(method)
    rec = _Record(sim)
    summary = sim.run()
    assert summary["status"].startswith("completed")
    assert not sim.compiled_steps and sim.integrator.A is None  # the per-step pass
    e = sim.energy.data()
    n = len(rec.rows)
    assert n == N_STEPS and e["step"].tolist() == list(range(n))
    assert len({r["h"] for r in rec.rows}) > 5  # the step changed
    n_dofs = summary["n_dofs"]
    assert np.abs(e["balance_error_rel"]).max() <= ledger(n, n_dofs)
    gap, sizes = rec.gap()
    scale = _scale(e)
    assert np.abs(gap).max() > 1e-6 * scale  # the terms are not nil
    # the column is the run's booked linear work less its split (each rounded on the
    # energy scale: the per-step pass's and the correction's sums, 8 roundings a dof a
    # step, the split's two dot products, 4 a dof) against the terms summed here (their
    # magnitudes' sum rounded, 6 a dof a term)
    bound = (rounding(8 * n_dofs * (np.arange(n) + 1) + 4 * n_dofs, scale)
             + rounding(6 * n_dofs, sizes))
    print(method, "work_gap - formula", np.abs(e["work_gap"] - gap).max(), "bound",
          bound.min(), "gap", np.abs(gap).max(), "scale", scale,
          "balance", np.abs(e["balance_error_rel"]).max())
    assert np.all(np.abs(e["work_gap"] - gap) <= bound)
    assert summary["energy"]["work_gap"] == e["work_gap"][-1]


def test_steps_that_do_not_change_leave_no_gap():
    """Equal steps through the varying path: work_gap is round-off, the ledger closes."""
    tm = meshing.coaxial_bars(radius=0.1, striker_length=0.4, target_length=0.4, h=0.04)
    limit = _limit(DeformableModel(tm, [Body("striker", LinearElastic(nu=0.3)),
                                        Body("target", LinearElastic(nu=0.3))]))
    sim = _bars("film", [0.7 * limit] * N_STEPS)
    summary = sim.run()
    e = sim.energy.data()
    scale, n_dofs = _scale(e), summary["n_dofs"]
    assert np.abs(e["work_gap"]).max() <= rounding(8 * n_dofs * (N_STEPS + 1), scale)
    assert np.abs(e["balance_error_rel"]).max() <= ledger(N_STEPS, n_dofs)


def test_a_bonded_linear_j2_body_under_a_load_keeps_the_identity():
    """A loaded linear disc bonded to a J2 disc that yields, under steps that change: the
    interface nodes and the loaded face are multiply-touched dofs. The ledger closes from
    its first row; work_gap is its formula (the J2 force's f_int^n from its pass, K u^n
    here); between two changes of step it does not move beyond round-off."""
    model = _bonded_with_a_loaded_face()
    held = model.facet_dofs("held", 1)
    limit = _limit(model, [ghosted_dofs(model, held)])
    pulse = loads.Trapezoid(peak=800e6, t_rise=1e-6, t_fall=4e-6, t_end=5e-6)
    load = loads.SurfaceLoad(model, "loaded_end", pulse)
    n_steps = 400
    factors = [0.9, 0.5, 0.7, 0.4, 0.8] * 8
    sim = Simulation(model, Settings(energy_every=1, output_every=n_steps, quiet=True),
                     fixed=[held], loads=[load], policy=StepSequence(_steps(limit, factors)))
    rec = _Record(sim)
    summary = sim.run()
    e = sim.energy.data()
    n, n_dofs = len(rec.rows), summary["n_dofs"]
    assert n == n_steps
    assert e["plastic_work"][-1] > 0.01 * e["external_work"][-1]  # the plate yielded
    assert np.abs(e["balance_error_rel"]).max() <= ledger(n, n_dofs)
    gap, sizes = rec.gap()
    scale = _scale(e)
    assert np.abs(gap).max() > 1e-6 * scale
    bound = (rounding(8 * n_dofs * (np.arange(n) + 1) + 4 * n_dofs, scale)
             + rounding(6 * n_dofs, sizes))
    print("bonded: work_gap - formula", np.abs(e["work_gap"] - gap).max(), "bound",
          bound.min(), "gap", np.abs(gap).max(), "scale", scale,
          "balance", np.abs(e["balance_error_rel"]).max())
    assert np.all(np.abs(e["work_gap"] - gap) <= bound)
    same = np.array([r["h_prev"] == r["h"] for r in rec.rows[1:]])  # no change at step n
    jumps = np.abs(np.diff(e["work_gap"]))[same]
    assert jumps.max() <= rounding(8 * n_dofs * n, scale)


def test_a_step_above_the_limit_is_refused():
    tm = meshing.coaxial_bars(radius=0.1, striker_length=0.4, target_length=0.4, h=0.04)
    steel = LinearElastic(nu=0.3)
    model = DeformableModel(tm, [Body("striker", steel), Body("target", steel)])
    limit = _limit(model)
    with pytest.raises(InputError, match="above the stable limit"):
        Simulation(model, Settings(quiet=True), policy=StepSequence([0.5 * limit, 1.5 * limit]))


def test_the_linear_split_closes_beside_a_finite_body():
    """A linear anvil bonded to a finite-strain J2 rod on one Q1 mesh, the step following the
    rod's cells (test_mixed_kinematics' body): with D tracked (the interface nodes take the
    linear and the finite increments), the linear pass's booked work equals its split
    1/2 (u^N)' K u^N + 1/2 h_{N+1/2} v^{N+1/2} . K u^N plus the 1/4 dh terms of every
    change of step, K u^n by a MatMult here, to round-off (without the correction on D the
    booking is 0.31 J against 0.58 J); and the two forces' shares still add up to the change of
    the kinetic energy."""
    from impact_fenics.integrator import Integrator
    from impact_fenics.stepping import FollowingStep
    from test_mixed_kinematics import T_END, _kinetic, _model, _squeeze

    model = _model()
    integ = Integrator(model, None, model.axis_dofs(), policy=FollowingStep(None, T_END))
    D = integ.track_increments()
    assert COMM.allreduce(int(D.size)) > 0  # the interface nodes
    integ.set_initial(None, _squeeze(model))
    k0 = _kinetic(integ)
    K, ku = integ.linear.K, integ.u_vec.duplicate()
    gap = size = 0.0
    n = 0
    while integ.t < T_END * (1.0 - 1e-12):
        K.mult(integ.u_vec, ku)
        u, v, h_prev = integ.u_owned.copy(), integ.v_owned.copy(), integ.step.h_prev
        integ.predict()
        integ.after_contact()
        h = integ.step.h
        if h_prev is not None:
            dv = v - integ.v_owned
            local = np.array([0.25 * (h - h_prev) * np.dot(dv, ku.array),
                              abs(0.25 * (h - h_prev)) * np.dot(np.abs(dv), np.abs(ku.array))])
            t = COMM.allreduce(local)
            gap += t[0]
            size += t[1]
        integ.advance()
        n += 1
    split = COMM.allreduce(0.5 * np.dot(u, ku.array) + 0.5 * h * np.dot(integ.v_owned, ku.array))
    work = COMM.allreduce(integ.linear.work_local)
    n_dofs = COMM.allreduce(model.n_owned)
    scale = max(abs(work), abs(split), k0)
    bound = rounding(8 * n_dofs * (n + 1) + 4 * n_dofs, scale) + rounding(6 * n_dofs, size)
    print("linear split: booked", work, "split + gap", split + gap, "gap", gap, "diff",
          work - split - gap, "bound", bound)
    assert abs(gap) > 1e3 * bound  # the step changed, and the terms count
    assert abs(work - (split + gap)) <= bound
    residual = _kinetic(integ) + COMM.allreduce(integ.linear.work_local
                                                + integ.finite[0].work_local) - k0
    assert abs(residual) <= ledger(n, n_dofs) * k0


def _bars_with(method, steps) -> Simulation:
    tm = meshing.coaxial_bars(radius=0.1, striker_length=0.4, target_length=0.4, h=0.04)
    steel = LinearElastic(nu=0.3)
    model = DeformableModel(tm, [Body("striker", steel), Body("target", steel)])
    limit = _limit(model)
    sim = Simulation(model, Settings(quiet=True), initial_velocity={"striker": (0.0, 5.0)},
                     policy=StepSequence([f * limit for f in steps]))
    sim.add_contact(pair_surfaces(model, "striker_contact", "target_contact"), method)
    return sim


def test_a_penalty_is_checked_at_every_step_the_run_takes():
    """beta = lambda_max of p h h_n S-scaled grows with the step: a fixed p that is stable at
    the first step (beta about 1 < 4/3) but not at a later, larger one is refused at set-up
    in one line; the same p under the small step alone is accepted."""
    from impact_fenics.contact import Penalty

    probe = _bars_with(Penalty(1e9), [0.4] * 20)
    beta_1 = probe.contacts[0].method.info["beta_max"]  # beta of p = 1e9 N/m at 0.4 x limit
    p = 1e9 / beta_1  # beta = 1 at 0.4 x the limit, about 5 at 0.9 x
    ok = _bars_with(Penalty(p), [0.4] * 20)
    assert ok.contacts[0].method.info["beta_max"] <= 4.0 / 3.0
    with pytest.raises(InputError, match="beta_max = .* is above the stable bound"):
        _bars_with(Penalty(p), [0.4] * 10 + [0.9] * 10)
