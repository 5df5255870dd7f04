"""A perfectly plastic J2 block compressed slowly in plane strain between frictionless
platens, at small strain (docs/plane_strain.md 5).

The half block 2 W0 x H0 (x in [0, W0] with symmetry = "x=0", the block generator's
triangles of alternating diagonals) rests on a frictionless base (u_y = 0 on y = 0, x
free); a rigid platen on its top is a crosshead of prescribed velocity, v ramped from 0 to
V over T_RAMP (58 elastic transit times H0 / c_L) and held after. Oracle: the flow between
frictionless platens with a free side is homogeneous, sigma_xx = 0, eps_out = 0, so once
the out-of-plane stress has settled halfway between the other two (the plastic flow
is then incompressible in the plane, d eps_p_out = 0), von Mises gives
|sigma_yy| = 2 sigma_y / sqrt(3). At small strain the geometry is the reference one: the
force per thickness on the half platen is F' = (2 / sqrt(3)) sigma_y W0, at every
height. The out-of-plane stress starts at first yield from sigma_out = nu sigma_yy
(|sigma_yy| = sigma_y / sqrt(1 - nu + nu^2)) and reaches -|sigma_yy| / 2 as the plastic
strain grows on a scale of the yield strain sigma_y / E = 1e-3: the readings are at 2 %
and 5 % of height reduction (20 and 50 yield strains). At small strain the lateral flow
v_x = V x / H0 does not accelerate once V is constant, so no inertia term.

Tolerance: the ramp's inertial stress rho H0 V / t_ramp over the flow stress (the
oscillation the ramp leaves is at most its inertial load), as for the finite-strain
block (tests/test_plane_strain_finite_scene.py). The prescribed ramp is the same
acceleration V / t_ramp as the heavy platen's force ramp it replaced (whose speed the
block's reaction changed by 2e-4 of V at most), so the bound is the same.

Locking: the homogeneous state is exactly representable on linear triangles (a uniform
strain), so volumetric locking cannot enter this oracle; the plane-strain thick cylinder
(tests/test_plane_strain_plastic.py) shows that P1 on alternating diagonals does not lock
where the plastic field is not homogeneous either. Triangles are therefore used (P1,
one point per cell), not Q1.
"""
import math

import numpy as np
from mpi4py import MPI

from impact_fenics import meshing
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.contact import DME, RigidBody, rigid_face
from impact_fenics.contact.prescribed import crosshead
from impact_fenics.geometry import PLANE_STRAIN, Geometry
from impact_fenics.materials import J2
from impact_fenics.simulation import Settings, Simulation
from roundoff import ledger

COMM = MPI.COMM_WORLD
RHO, E, NU, SY = 7850.0, 200e9, 0.3, 200e6  # kg/m^3, Pa, -, Pa
W0 = H0 = 0.01  # m: the half width and the height
T = 0.01  # m, the slab's thickness
H = 0.00125  # m, the cells (8 x 8 squares, two triangles each)
V_PLATEN, T_RAMP = 2.0, 100e-6  # m/s, s: the crosshead's speed and ramp
READINGS, HALF_WINDOW = (0.02, 0.05), 0.0025


def _platen_run():
    """The history (time, platen_force, platen_u, platen_v) and the summary."""
    t_end = T_RAMP / 2 + (max(READINGS) + 2 * HALF_WINDOW) * H0 / V_PLATEN
    tmesh = meshing.block(width=W0, height=H0, h=H, comm=COMM)
    material = J2(E=E, nu=NU, density=RHO, yield_stress=SY, hardening=0.0)
    model = DeformableModel(tmesh, [Body("block", material)],
                            geometry=Geometry(PLANE_STRAIN, T, "x=0"))
    platen = RigidBody("platen", math.inf, prescribed=crosshead("platen", V_PLATEN, T_RAMP))
    sim = Simulation(model, Settings(quiet=True, plots=False, fields=False, timers=False,
                                     out=None, t_end=t_end, cfl=0.5, history_every=1),
                     fixed=[model.facet_dofs("bottom", 1)])
    sim.add_contact(rigid_face(model, "top", W0, "platen"), DME(), rigid=platen)
    summary = sim.run()
    return summary, sim.history.data()


def test_small_strain_j2_block_between_platens_flows_at_2_sigma_y_over_sqrt3():
    summary, hist = _platen_run()
    k = 2 / math.sqrt(3) * SY  # Pa, the plane-strain flow stress
    ratio = hist["platen_force"] / (k * W0 * T)
    reduction = -hist["platen_u"] / H0
    c_l = math.sqrt(E * (1 - NU) / ((1 + NU) * (1 - 2 * NU)) / RHO)
    assert T_RAMP >= 10 * H0 / c_l  # slow: the ramp spans many elastic transits
    tol = RHO * H0 * V_PLATEN / T_RAMP / k  # the ramp's inertial stress / the flow stress
    for at in READINGS:
        window = np.abs(reduction - at) < HALF_WINDOW
        assert window.sum() > 20
        mean = float(ratio[window].mean())
        spread = float(ratio[window].max() - ratio[window].min())
        print(f"at {at:.0%} reduction: F' / ((2/sqrt3) sigma_y W0) - 1 = {mean - 1:+.2e} "
              f"(ringing spread {spread:.1e}, tolerance {tol:.1e})")
        assert abs(mean - 1) <= tol
    assert summary["energy_balance_error_rel"] <= ledger(summary["n_steps"], summary["n_dofs"])
