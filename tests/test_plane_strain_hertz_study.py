"""Hertz's line contact in plane strain: a long elastic cylinder pressed slowly on a rigid
plane (docs/plane_strain.md 5).

A quarter of the section (x >= 0 with symmetry = "x=0": the half, and of it the lower
quarter disc of radius R below its diametral plane, which carries the load as a uniform
pressure) on the wall y = 0, its contact zone meshed at b/n (n = 5, 10, 20 nodes across
the half-width b), the pressure rising linearly over 30 transit times R/c_L. Hertz for a
cylinder on a rigid plane, per unit length F' (N/m): E* = E/(1 - nu^2), R* = R,

    b = sqrt(4 F' R* / (pi E*)),    p0 = 2 F' / (pi b),    p(x) = p0 sqrt(1 - x^2/b^2).

Read at the ramp's end against F' = 2 Σ λ_n / t of that same step (the wall's force, so
that the body's slow oscillation about the quasi-static state does not enter): the
half-width by the pressure's second moment (Hertz's Σ x^2 p / Σ p = b^2/4, so
b = 2 sqrt(Σ x_i^2 λ_i / Σ λ_i) over the nodes of the half), the peak pressure as the
x = 0 node's force over its tributary length (half its segment, in the half model). Both
errors fall with h; what is left at the finest mesh is of the order of what Hertz leaves
out, (b/R)^2 = 2.3e-3 (a half-space, not a cylinder), and the dynamic residue of the
ramp.

The same against an elastic block of the same steel under the cylinder (x in [0, R],
y in [-R, 0], its bottom held in y), node to segment with the cylinder's arc the slave:
1/E* = 2 (1 - nu^2)/E, R* = R.
"""
import math

import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics import loads
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.contact import FILM
from impact_fenics.contact.plane import plane_below, wall_part
from impact_fenics.contact.segments import node_to_segment
from impact_fenics.geometry import PLANE_STRAIN, Geometry
from impact_fenics.materials import LinearElastic
from impact_fenics.meshing import cylinder_on_block
from impact_fenics.simulation import Settings, Simulation

COMM = MPI.COMM_WORLD
# a study (`make study-hertz-cylinder`, about 20 s serial): six presses of up to 40,000 steps
pytestmark = pytest.mark.study
STEEL = LinearElastic(E=200e9, nu=0.3, density=7850.0)
R, T = 0.01, 0.01  # m: the cylinder's radius, the slab's thickness
B_OVER_R = 0.05  # the half-width aimed at (Hertz: b/R <= 0.1)
E_STAR = STEEL.E / (1 - STEEL.nu ** 2)  # Pa, against a rigid plane
C_L = math.sqrt(STEEL.E * (1 - STEEL.nu) / ((1 + STEEL.nu) * (1 - 2 * STEEL.nu)) / STEEL.density)


def _pressed(per_b: int, block: bool = False):
    """The quarter disc pressed on the wall, or with ``block`` on the elastic block (node to
    segment, the disc's arc the slave, the block's bottom held in y), with per_b nodes
    across the aimed b: (F' (N/m), F' aimed at, b from the second moment, p0 from the
    x = 0 node, the nodes within Hertz's b, E* (Pa))."""
    e_star = E_STAR / 2 if block else E_STAR  # two equal bodies: 1/E* = 2 (1 - nu^2) / E
    b_aim = B_OVER_R * R
    f_aim = math.pi * e_star * b_aim ** 2 / (4 * R)  # N/m
    h_c = b_aim / per_b
    bodies = [Body("cylinder", STEEL)] + ([Body("block", STEEL)] if block else [])
    model = DeformableModel(cylinder_on_block(R, 0.0, R, R, h_c, R / 10, 2 * b_aim, quarter=True,
                                              block=block, comm=COMM), bodies,
                            geometry=Geometry(PLANE_STRAIN, T, "x=0"))
    dt = 0.25 * h_c / C_L  # s, below the stable step of the finest cells
    t_ramp = 30 * R / C_L
    pressure = loads.Trapezoid(f_aim / (2 * R), t_ramp, 10 * t_ramp, 20 * t_ramp)  # Pa
    load = loads.SurfaceLoad(model, "cylinder_top", pressure, traction=(0.0, -1.0))
    fixed = [model.facet_dofs("block_bottom", 1)] if block else None
    sim = Simulation(model, Settings(dt=dt, n_steps=int(t_ramp / dt) + 1, out=None,
                                     quiet=True), loads=[load], fixed=fixed)
    if block:
        cons = node_to_segment(model, "cylinder_contact", "block_top")
        contact = sim.add_contact(cons, FILM())
        x = np.asarray(cons.slave_xy[:, 0])
    else:
        arc = np.unique(model.facet_dofs("cylinder_contact", 1) // 2)
        cons = plane_below(COMM, arc, model.node_xy, model.offset, 0.0, model.length_scale)
        contact = sim.add_contact(cons, FILM(), rigid=wall_part())
        x = np.asarray(cons.r)
    sim.run()
    lam = np.where(contact.active, contact.force, 0.0)  # N, every constraint on every rank
    f_prime = 2 * lam.sum() / T
    b_fe = 2 * math.sqrt(float((x * x * lam).sum() / lam.sum()))
    order = np.argsort(x)
    p0_fe = lam[order[0]] / (0.5 * (x[order[1]] - x[order[0]]) * T)
    b_hertz = math.sqrt(4 * f_prime * R / (math.pi * e_star))
    n_b = int(np.count_nonzero((lam > 0) & (x <= b_hertz)))
    return f_prime, f_aim, b_fe, p0_fe, n_b, e_star


@pytest.mark.parametrize("block", [False, True], ids=["wall", "block"])
def test_hertz_cylinder_converges_with_h(block):
    """5, 10 and 20 nodes across b (b/R = 0.048), on the wall and on an elastic block
    (node to segment): the errors of b and p0 fall at each halving of h, the finest
    within 2 (b/R)^2 = 5e-3 (what Hertz leaves out, a half-space for a cylinder and for
    the block's finite depth, plus the ramp's residue); at least 10 nodes across b from
    the second mesh on."""
    errors = []
    for per_b in (5, 10, 20):
        f_prime, f_aim, b_fe, p0_fe, n_b, e_star = _pressed(per_b, block)
        b = math.sqrt(4 * f_prime * R / (math.pi * e_star))
        p0 = 2 * f_prime / (math.pi * b)
        e_b, e_p = b_fe / b - 1, p0_fe / p0 - 1
        print(f"{'block' if block else 'wall'}, {per_b} per b: F' = {f_prime:.4g} N/m "
              f"({f_prime / f_aim:.3f} of the load's), b/R = {b / R:.4f}, {n_b} nodes in b; "
              f"b {b_fe * 1e3:.5f} mm against {b * 1e3:.5f} mm ({e_b:+.2e}), p0 "
              f"{p0_fe / 1e9:.4f} GPa against {p0 / 1e9:.4f} GPa ({e_p:+.2e})")
        assert b / R <= 0.1
        if per_b >= 10:
            assert n_b >= 10
        errors.append((abs(e_b), abs(e_p)))
    errors = np.array(errors)
    assert np.all(np.diff(errors, axis=0) < 0.0), errors
    assert np.all(errors[-1] <= 2 * B_OVER_R ** 2), errors
