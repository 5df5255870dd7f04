"""Rigid parts in contact sets: a moving part in one set only, fixed parts in any number,
and the step's constants rewritten by set_step (serial and mpirun -n 2).

The oracles are the definitions: S = h_{n+1/2} h_n G M^-1 G' = diag(d) + kappa 1 1'
with d_i = h_{n+1/2} h_n / m_i under a rigid face and kappa = h_{n+1/2} h_n / M (0 for
a fixed part), velocities moved by h_n f / m (the rows h_n / m) and reactions
m dv / h_n (the rows m / h_n), written here as numpy expressions on the set's masses.
Under a constant step they must be the expressions of a constant step (dt^2, dt / m,
m / dt) bit for bit, and returning to the first step must restore every row exactly.
"""
import numpy as np
import pytest

from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.contact import DME, FILM, Penalty, RigidBody, rigid_face
from impact_fenics.contact.state import DT, H_AVG, KAPPA, RIGID_MASS
from impact_fenics.errors import InputError
from impact_fenics.materials import STEEL
from impact_fenics.simulation import Settings, Simulation

MASS = 1e3  # kg, the punch


def _sim(punch_mesh):
    model = DeformableModel(punch_mesh, [Body("block", STEEL)])
    return model, Simulation(model, Settings(cfl=0.9, n_steps=10, quiet=True, plots=False),
                             fixed=[model.facet_dofs("bottom", 1)])


def test_a_moving_rigid_part_in_two_sets_is_refused(punch_mesh):
    """Sets correct one after another: a moving part in two would be a Gauss-Seidel sweep,
    not the coupled solve of its kappa 1 1'. Refused in one line naming both sets."""
    model, sim = _sim(punch_mesh)
    punch = RigidBody("punch", MASS)
    sim.add_contact(rigid_face(model, "surface", 1.0, "punch"), FILM(), rigid=punch)
    with pytest.raises(InputError) as err:
        sim.add_contact(rigid_face(model, "bottom", 1.0, "punch"), DME(), rigid=punch)
    text = str(err.value)
    assert "\n" not in text
    assert text.startswith("rigid body 'punch' is in two contact sets, 'surface'/'punch' and "
                           "'bottom'/'punch': a moving rigid part belongs to one set")
    assert len(sim.contacts) == 1  # nothing of the refused set was added


def test_a_fixed_part_may_be_in_several_sets(punch_mesh):
    """A fixed part has zero inverse mass: kappa = 0 and h/m = m/h = 0 at its slot in every
    set that holds it, so no set moves it and none couples through it."""
    model, sim = _sim(punch_mesh)
    seat = RigidBody("seat", 1.0, fixed=True)
    assert seat.mass == np.inf
    for radius, method in ((1.0, FILM()), (0.5, Penalty("scaled")), (0.75, DME())):
        c = sim.add_contact(rigid_face(model, "surface", radius, "seat"), method, rigid=seat)
        assert c.kappa == 0.0 and c.dt_over_m[-1] == 0.0 and c.m_over_dt[-1] == 0.0
    assert len(sim.contacts) == 3
    with pytest.raises(InputError, match="a fixed part has no velocity"):
        RigidBody("seat", 1.0, v=1.0, fixed=True)


@pytest.mark.parametrize("method", ["penalty", "film", "dme"])
def test_set_step_rewrites_every_constant_that_holds_the_step(punch_mesh, method):
    model, sim = _sim(punch_mesh)
    chosen = {"penalty": lambda: Penalty("scaled", beta_target=0.9), "film": FILM,
              "dme": DME}[method]()
    c = sim.add_contact(rigid_face(model, "surface", 1.0, "punch"), chosen,
                        rigid=RigidBody("punch", MASS))
    dt = c.dt
    nd = c.n_deformable
    m = c.mass.copy()
    # a constant step: today's expressions, bit for bit
    assert np.array_equal(c.dt_over_m, dt / m) and np.array_equal(c.m_over_dt, m / dt)
    assert c.kappa == dt ** 2 / m[nd]
    assert np.array_equal(c.d, dt ** 2 * (1.0 / m[c.lo] + 0.0))
    first = c._floats.copy(), c._misc.copy(), c.kappa
    h, h_avg = 0.8 * dt, 0.9 * dt
    c.set_step(h, h_avg)
    assert np.array_equal(c.dt_over_m, h_avg / m) and np.array_equal(c.m_over_dt, m / h_avg)
    assert c.kappa == h * h_avg / m[nd]
    assert np.array_equal(c.d, h * h_avg * (1.0 / m[c.lo] + 0.0))
    assert np.array_equal(c.d_inv, 1.0 / c.d)
    assert (c._misc[DT], c._misc[H_AVG], c._misc[KAPPA], c._misc[RIGID_MASS]) == (
        h, h_avg, c.kappa, MASS)
    if method == "penalty":  # the scaled choice p = beta / (d (1 + kappa sum 1/d))
        scale = 0.9 / (1.0 + c.kappa * float(np.sum(1.0 / c.d)))
        assert np.array_equal(c.p, scale / c.d)
    c.set_step(dt, dt)
    assert np.array_equal(c._floats, first[0]) and np.array_equal(c._misc, first[1])
    assert c.kappa == first[2]
