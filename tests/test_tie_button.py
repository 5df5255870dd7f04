"""The blow of percussive drilling through a tied finite-strain button (docs/one_loop.md,
"A tie"); serial and mpirun -n 2.

Scene (:func:`impact_fenics.scenes.bit_button_rock`): the rigid bit of the bit-rock scene
(0.5 kg, driven by a rod of impedance Z carrying an incident force wave F_i(t)) tied by
its face to the top of a steel button (finite-strain J2 on Q1, R = 5 mm, L = 5 mm, 4 x 4
cells), whose face meets a granite block (linear elastic, small strain, Q1 cells of the
button's size) through node-to-segment contact (DME or FILM). The block is free (no dof
held in z), as wide and deep as the waves reach in t_end, so nothing but the rod acts in
z. The oracles do not come from any single piece under test:

1. the ledger: kinetic + strain + plastic + work gap - contact work = E_0 + the rod's
   work on the bit (the kinetic identity of the half-step scheme) within roundoff.ledger
   at every row; the rod's work is the booked wave balance incident - reflected;
2. the tie does no work: its set's work is 0 to round-off from step 1 on (every tied slot
   and the bit at one velocity before and after each step, docs/one_loop.md "A tie");
3. the z momentum of bit + button + rock equals the impulse of the rod's force,
   sum h_n F^n with F^n = -2 F_i(t^n) - Z (v^{n-1/2} + v^{n+1/2}) / 2 recomputed here
   from the bit's recorded velocities, to round-off;

and the rock's energy (kinetic + stored) at t_end beside the rigid flat bit's of the same
radius on the same rock, cell for cell (:func:`~impact_fenics.scenes.rigid_bit_on_rock_block`),
printed, with the sanity bound 0 < rock energy <= the energy the rod delivered.
"""
import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics import loads, scenes
from impact_fenics.materials import FiniteJ2, NeoHookean
from impact_fenics.operators import assemble_stiffness
from impact_fenics.simulation import Settings
from roundoff import ledger

COMM = MPI.COMM_WORLD
R = 5e-3  # m, the button's radius and length
N_R = 4  # cells across the button (h = 1.25 mm)
# a mild steel button (yield 200 MPa): the blow's push, up to 2 x 150 kN over pi R^2, yields
# it, so the plastic work enters the ledger (a carbide button would stay elastic)
BUTTON = FiniteJ2(E=200e9, nu=0.3, density=7850.0, yield_stress=0.2e9, hardening=1e9)
# the elastic variant: a neo-Hookean button of the same constants (no plastic work)
ELASTIC_BUTTON = NeoHookean(E=200e9, nu=0.3, density=7850.0)
PULSE = loads.Trapezoid(150e3, 2e-6, 8e-6, 1e-5)  # N: the bit-rock blow's peak, short
DT = 2.0 ** -24  # s (6.0e-8: 0.28 of the button's cell limit h / c_L = 2.1e-7 s at set-up)
T_END = 2e-5  # s: the pulse and as long again (336 steps, the last one clipped to 3.2e-8 s)


def _settings(**kw) -> Settings:
    return Settings(quiet=True, plots=False, timers=False, fields=False, energy_every=1,
                    output_every=1, **kw)


class _TieWatch:
    """After each step of the tie's set: its work (J), and sum m |v| over every dof of the
    run plus the bit's M |v| (kg m/s, the momentum's scale)."""

    def __init__(self, sim):
        c, integ = sim.contacts[0], sim.integrator
        self.work, self.scale = [], []
        step = c.step

        def watched():
            step()
            self.work.append(c.contact_work)
            local = float(np.dot(integ.mass[: integ.v_owned.size], np.abs(integ.v_owned)))
            self.scale.append(COMM.allreduce(local) + c.rigid.mass * abs(c.rigid.v))

        c.step = watched


def _rock_energy(sim, body: str) -> float:
    """The rock's kinetic energy 1/2 m v^2 (v^{N-1/2}) and stored energy 1/2 u' K u (u^N,
    K of the linear parts: the rock alone) at the run's end (J)."""
    model, integ = sim.model, sim.integrator
    dofs = np.concatenate([model.body_dofs(body, 0), model.body_dofs(body, 1)])
    dofs = np.unique(dofs[dofs < integ.v_owned.size])
    kinetic = 0.5 * float(np.dot(integ.mass[dofs], integ.v_owned[dofs] ** 2))
    K = assemble_stiffness(model, parts=[p for p in model.parts if p[0].linear])
    u, ku = K.createVecs()
    u.array[:] = 0.0
    u.array[dofs] = integ.u_owned[dofs]
    K.mult(u, ku)
    stored = 0.5 * float(np.dot(u.array, ku.array))
    return COMM.allreduce(kinetic + stored)


@pytest.fixture(scope="module", params=[("dme", "j2"), ("film", "j2"), ("dme", "neo_hookean")],
                ids=["dme_j2", "film_j2", "dme_neo_hookean"])
def blow(request):
    method, material = request.param
    sim = scenes.bit_button_rock(_settings(), BUTTON if material == "j2" else ELASTIC_BUTTON,
                                 button_radius=R, button_length=R, n_r=N_R, incident=PULSE,
                                 method=method, t_end=T_END, dt=DT)
    watch = _TieWatch(sim)
    summary = sim.run()
    assert sim.status == "completed"
    return f"{method}, {material}", sim, summary, watch


def test_the_ledger_closes(blow):
    method, sim, summary, _ = blow
    e = sim.energy.data()
    bit = sim.contacts[0].rigid
    n = sim.n_steps
    bound = ledger(n, summary["n_dofs"])
    if COMM.rank == 0:
        print(f"\nbutton ({method}): {n} steps; incident {bit.wave_incident:.6g} J, reflected "
              f"{bit.wave_reflected:.6g} J, delivered {bit.wave_delivered:.6g} J, external work "
              f"{e['external_work'][-1]:.6g} J; kinetic {e['kinetic'][-1]:.6g} J, strain "
              f"{e['strain'][-1]:.6g} J, plastic {e['plastic_work'][-1]:.6g} J, contact "
              f"{e['contact_work'][-1]:.3g} J, activation {e['activation_loss'][-1]:.3g} J, "
              f"work gap {e['work_gap'][-1]:.3g} J; balance error (rel) max "
              f"{np.abs(e['balance_error_rel']).max():.3g} (bound {bound:.3g})")
    if "j2" in method:  # the button yielded: the plastic work is in the sum
        assert e["plastic_work"][-1] > 0.0
    else:
        assert e["plastic_work"][-1] == 0.0
    assert np.all(np.abs(e["balance_error_rel"]) <= bound)
    # the rod's work on the bit is the wave balance's delivered energy (the same sum)
    assert abs(e["external_work"][-1] - bit.wave_delivered) <= bound * bit.wave_incident


def test_the_tie_does_no_work(blow):
    """Each step's tie work is 1/2 (v_c^old + v_c) sum m (v_c - v~) = 0 by the momentum
    balance: what is left is the roundings of the slots' terms, the ledger's count on
    the run's energy scale, the incident energy (no energy of the run exceeds it)."""
    method, sim, summary, watch = blow
    bit = sim.contacts[0].rigid
    bound = ledger(sim.n_steps, summary["n_dofs"]) * bit.wave_incident
    work = np.array(watch.work)
    if COMM.rank == 0:
        print(f"\nbutton ({method}): tie work max {np.abs(work).max():.3g} J over "
              f"{work.size} steps (bound {bound:.3g} J)")
    assert work.size == sim.n_steps
    assert np.abs(work).max() <= bound


def test_the_momentum_is_the_rods_impulse(blow):
    """p_z(t^{n+1}) of bit + button + rock (energy.csv's momentum_z, v^{n+1/2}) against
    sum_k h_k F^k (h_k the velocity's step), F^k the rod's force recomputed from F_i(t^k)
    and the bit's recorded v^{k-1/2}, v^{k+1/2}. Both sides round per step as a ledger does, on the momentum's
    scale sum m |v| (the largest over the run)."""
    method, sim, summary, watch = blow
    e, h = sim.energy.data(), sim.history.data()
    v = np.concatenate([[0.0], h["c0_bit_v"]])
    dt = h["dt"]  # h_{n+1/2}, the position's step; t^n = t^{n+1} - h_{n+1/2}
    t_n = h["time"] - dt
    f_i = np.array([PULSE(t) for t in t_n])
    force = -2.0 * f_i - scenes.ROD_IMPEDANCE * 0.5 * (v[:-1] + v[1:])
    # the velocity's step h_n = (h_{n-1/2} + h_{n+1/2}) / 2 (h_{-1/2} = h_{1/2}): it differs
    # from dt at the clipped last step, where h_{n+1/2} F^n would miss 7e-4 kg m/s
    h_n = 0.5 * (np.concatenate([dt[:1], dt[:-1]]) + dt)
    impulse = np.cumsum(h_n * force)
    p = e["momentum_z"]
    assert p.size == impulse.size
    bound = ledger(sim.n_steps, summary["n_dofs"]) * max(watch.scale)
    drift = np.abs(p - impulse).max()
    if COMM.rank == 0:
        print(f"\nbutton ({method}): momentum {p[-1]:.6g} kg m/s, rod impulse "
              f"{impulse[-1]:.6g}; largest difference {drift:.3g} (bound {bound:.3g})")
    assert drift <= bound


def test_rock_energy_beside_the_rigid_bit(blow):
    """The same blow with the rigid flat bit of the button's radius straight on the same
    rock (cell for cell): the rock's energy at t_end of both, printed; each is > 0 and at
    most the energy the rod delivered (the ledger's other terms are >= 0)."""
    method, sim, summary, _ = blow
    rock_button = _rock_energy(sim, "anvil")
    delivered = sim.contacts[0].rigid.wave_delivered
    rigid = scenes.rigid_bit_on_rock_block(
        _settings(t_end=T_END, dt=T_END / sim.n_steps), scenes.make_method(method.split(",")[0]),
        bit_radius=R,
        h=R / N_R, rock_radius=sim.model.tmesh.info["anvil_cells"][0] * R / N_R,
        rock_depth=sim.model.tmesh.info["anvil_cells"][1] * R / N_R, incident=PULSE)
    rigid.run()  # as many equal steps (5.95e-8 s) to the same t_end
    assert rigid.n_steps == sim.n_steps and rigid.integrator.t == pytest.approx(T_END)
    rock_rigid = _rock_energy(rigid, "block")
    bit = rigid.contacts[0].rigid
    f_button = np.abs(sim.history.data()["c1_contact_force"]).max()
    f_rigid = np.abs(rigid.history.data()["bit_force"]).max()
    if COMM.rank == 0:
        print(f"\nbutton ({method}): rock energy at t_end {rock_button:.6g} J of "
              f"{delivered:.6g} J delivered (incident {sim.contacts[0].rigid.wave_incident:.6g}"
              f" J), peak contact force {f_button:.6g} N; rigid bit: rock energy "
              f"{rock_rigid:.6g} J of {bit.wave_delivered:.6g} J delivered, peak force "
              f"{f_rigid:.6g} N")
    assert 0.0 < rock_button <= delivered
    assert 0.0 < rock_rigid <= bit.wave_delivered
