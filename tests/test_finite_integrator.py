"""A finite-strain body stepped by the one integrator (its finite-strain force, the
following step) equals the finite-strain driver's own run.

Oracle: the previous path, ``FiniteRun`` (kept while its loop moves: its Taylor tables
are checked against the literature and a refined mesh in test_taylor_study), run on the
same mesh. The integrator builds the same force, the same lumped mass (the Q1 rule), the
same coefficients -1/m, the same steps (the policy bound to the force's current cells,
re-estimated every 10 steps, the last clipped to t_end) and the same half steps (the
point updates take the step just taken): the same operations in the same order, so
u, v, the points' state, the number of steps and t agree bit for bit (array_equal), on
any number of ranks (both runs share the mesh and its partition). Every contact
method of the plane and the three finite-strain materials (Johnson-Cook reads the
step in its rate term) take part, over an impact that yields the bar's foot.
"""
import numpy as np
import pytest
from mpi4py import MPI
from petsc4py import PETSc

from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.contact.plane import FixedPlane
from impact_fenics.finite_run import FiniteRun, FiniteSettings, quad_bar
from impact_fenics.integrator import Integrator
from impact_fenics.materials import FiniteJ2, JohnsonCook, NeoHookean
from impact_fenics.quad_meshes import tag_rectangle
from impact_fenics.stepping import FollowingStep

COMM = MPI.COMM_WORLD
RADIUS, LENGTH, N_R, N_Z = 3.2e-3, 32.4e-3, 2, 20  # m: the Taylor bar at a coarse mesh
SPEED = 227.0  # m/s, towards the plane z = 0 it starts on
T_END = 12e-6  # s: 100-143 steps; the step falls to half as the foot flattens (eps_p to 1.3)

CASES = {
    "j2-dme": (FiniteJ2(E=117e9, nu=0.35, density=8930.0, yield_stress=400e6,
                        hardening=100e6), "dme"),
    "johnson_cook-film": (JohnsonCook(), "film"),
    "neo_hookean-penalty": (NeoHookean(E=117e9, nu=0.35, density=8930.0), "penalty"),
}


@pytest.mark.parametrize("case", list(CASES))
def test_the_integrator_steps_a_finite_strain_body_as_the_finite_driver(case):
    material, method = CASES[case]
    mesh = quad_bar(COMM, RADIUS, LENGTH, N_R, N_Z)
    run = FiniteRun(mesh, material, FiniteSettings(t_end=T_END, quiet=True, plots=False),
                    velocity=(0.0, -SPEED), wall=method, z_wall=0.0)
    nodes = run.wall.nodes.copy()  # its candidates: the owned boundary nodes
    summary = run.run()
    assert summary["status"].startswith("completed")

    model = DeformableModel(tag_rectangle(mesh, "bar"), [Body("bar", material)])
    integ = Integrator(model, None, model.axis_dofs(), policy=FollowingStep(None, T_END))
    v0 = np.zeros(model.n_owned)
    v0[1::2] = -SPEED
    integ.set_initial(None, v0)
    plane = FixedPlane(COMM, nodes, model.node_xy, model.offset, integ.mass, integ.u_owned,
                       integ.v_owned, method, 0.0, dt=integ.dt)
    force = integ.finite[0]
    while integ.t < T_END * (1.0 - 1e-12):  # the driver's end test
        integ.predict()
        plane.step(integ.u_owned, integ.v_owned, integ.step.h, integ.step.h_avg,
                   force.f_owned)
        integ.advance()

    assert integ.n == summary["n_steps"]
    assert integ.t == summary["t_end"]
    assert np.array_equal(integ.mass, run.mass)
    assert np.array_equal(integ.u_owned, run.u_owned)
    assert np.array_equal(integ.v_owned, run.v)
    # the points at u^N, as the driver leaves them (its final row: one more evaluation,
    # the points' step the last one taken)
    force.set_step(integ.step.h, integ.step.h)
    integ.u_vec.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
    force.evaluate()
    assert np.array_equal(force.state, run.force.state)
    # the impact did what the oracle needs: the foot touched and yielded (J2, JC)
    assert COMM.allreduce(plane.contact_loss_local) > 0.0 or method == "penalty"
    if not isinstance(material, NeoHookean):
        assert COMM.allreduce(float(force.state[..., 0].max(initial=0.0)), op=MPI.MAX) > 0.0
