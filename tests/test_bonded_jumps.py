"""DME's position jumps on a node that a small-strain body and a body booked by the kinetic
identity share.

Scene: a Q1 cylinder 4 mm x 8 mm of 1 mm squares, its core (r < 2 mm) a small-strain J2
steel, its ring (r > 2 mm) a finite-strain J2 copper (the step following its cells) or a
linear elastic one (steps of 0.35 and 0.5 of the element bound in turn: its per-step
pass), bonded along r = 2 mm (the two bodies' cells share the nodes of that line),
falling at 150 m/s onto a fixed wall by DME 0.1234 mm below it. The foot's node at
r = 2 mm is both bodies' and touches the wall: its jumps j = u^{n+1} - u^n - h v^{n+1/2}
are work on the core (its stored energy is read from its positions, the trapezoid of
f . du) and on none of the ring (its work is the kinetic identity's, which no jump
enters), so the jump is booked as 1/2 j . (f_core^{n-1} + f_core^n) on it, the core's
share of the force, not the two bodies' sum (one_loop.md 4.7).

Oracle: the ledger, kinetic + strain + plastic + work_gap - contact work = E_0, an
identity of the scheme, within roundoff.ledger (32 roundings a dof a step, 4 a dof for
the sums) of E_0 at every row of energy.csv. Booked against the sum of both bodies'
forces it missed by 5.8e-5 of E_0 with the finite ring (1.2e8 times that bound, 59 steps)
and by 1.5e-4 with the linear one (2.6e8 times, 69 steps).

Runs unchanged on 1, 2 and 3 ranks.
"""
import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics import scenes
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.contact.plane import boundary_nodes, plane_below, wall_part
from impact_fenics.materials import J2, FiniteJ2, LinearElastic, is_finite
from impact_fenics.simulation import Settings, Simulation
from impact_fenics.stability import critical_dt, element_omega_bounds
from impact_fenics.stepping import FollowingStep, StepSequence
from roundoff import ledger
from two_halves import two_halves

COMM = MPI.COMM_WORLD
R1, Z1, N_R, N_Z = 4e-3, 8e-3, 4, 8  # m: 4 x 8 squares of 1 mm
CORE = J2(E=200e9, nu=0.3, density=7850.0, yield_stress=300e6, hardening=1e9)
RING = FiniteJ2(E=117e9, nu=0.35, density=8930.0, yield_stress=200e6, hardening=100e6)
LINEAR_RING = LinearElastic(E=117e9, nu=0.35, density=8930.0)
V0, GAP, T_END = 150.0, 1.234e-4, 4e-6  # m/s, m (the wall below the foot), s


def _bonded_on_a_dme_wall(ring) -> Simulation:
    tm = two_halves(COMM, (0.0, 0.0), (R1, Z1), N_R, N_Z, True, ("core", "ring"), split=0)
    model = DeformableModel(tm, [Body("core", CORE), Body("ring", ring)])
    nodes = boundary_nodes(model.V, model.V.dofmap.index_map.size_local)
    if is_finite(ring):
        policy = FollowingStep(None, T_END)
    else:  # two bodies at small strain: steps that change at every step, within the bound
        axis = model.axis_dofs(owned=False)
        limit = critical_dt(max(element_omega_bounds(model, axis).values()))
        n = int(np.ceil(T_END / (0.425 * limit)))
        policy = StepSequence([(0.5 if k % 2 else 0.35) * limit for k in range(n)], limit)
    sim = Simulation(model, Settings(quiet=True, plots=False, timers=False, fields=False,
                                     energy_every=1), policy=policy)
    v0 = np.zeros(model.n_owned)
    v0[1::2] = -V0
    sim.integrator.set_initial(None, v0)
    sim.add_contact(plane_below(COMM, nodes, model.node_xy, model.offset, -GAP, Z1),
                    scenes.make_method("dme"), wall_part())
    return sim


@pytest.mark.parametrize("ring", [RING, LINEAR_RING], ids=["finite", "linear"])
def test_a_jump_on_a_bonded_node_books_the_small_strain_share(ring):
    sim = _bonded_on_a_dme_wall(ring)
    model = sim.model
    shared = np.intersect1d(model.body_dofs("core", 1), model.body_dofs("ring", 1))
    summary = sim.run()
    assert sim.status == "completed" and summary["eps_p_max"] > 0.0
    (wall,) = sim.contacts
    # the bonded foot node's constraint: r = 2 mm, Z = 0 (its gap at rest GAP, the top's Z1)
    foot = (np.abs(wall.r - 0.5 * R1) < 1e-9 * R1) & (wall.b < 2.0 * GAP)
    assert foot.sum() == 1
    # the bonded node is both bodies' (its dof owned by one rank) and touched the wall
    assert COMM.allreduce(int(shared.size)) == N_Z + 1
    # its slot's jumps are booked apart, on the core's force, and it jumped
    assert wall.jump_book[wall.nodes[foot][0]] == 0.0
    assert wall.jump_book[: wall.n_deformable].max() == 1.0  # the core's own nodes
    assert COMM.allreduce(sim._shared_jumps.work_local) != 0.0
    e = sim.energy.data()
    assert e["contact_work"].min() < -1.0  # the wall took energy
    n_dofs = COMM.allreduce(model.n_owned)
    bound = ledger(sim.n_steps, n_dofs)
    worst = np.abs(e["balance_error"]).max() / sim.ledger.E0
    if COMM.rank == 0:
        print(f"\nbonded DME: |balance| / E0 = {worst:.3g}, bound {bound:.3g} "
              f"({sim.n_steps} steps, {n_dofs} dofs)")
    assert worst <= bound
