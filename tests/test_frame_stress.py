"""Every field of a fields.xdmf frame of a finite-strain body belongs to the same t^n.

A frame is written after the step that moved u^n to u^{n+1}; the points then hold the
update at u^n. The frame's Cauchy stress must be that of the displacement it writes.

Oracle (closed form, computed here from the frame's own written geometry and
displacement, not from the code under test): a neo-Hookean body, tau = mu (b - I) +
lambda ln J I, on Q1 cells with mean dilatation, F_bar_q = (J_bar / J_q)^(1/3) F_q
(axisymmetric; the in-plane block with the power 1/2 in plane strain, F_out = 1),
J_bar = sum_q w_q J_q / sum_q w_q, 2 x 2 Gauss points, w_q = |det dX/dxi| (times R_q
in the axisymmetric case). The cell's Cauchy stress is sum_q w_q tau_q / (V_0 J_bar).
The material is path independent, so this is the stress of the written u alone.

Runs: the plane-strain strip on the wall (scenes/plane_strain_finite_wall.toml at
nu = 0.3, so that every component is non-zero) and an axisymmetric neo-Hookean bar on the
wall, frames every 3 steps during the impact, on 1, 2 or 3 ranks (each piece checked).

Tolerance: round-off. Each entry of F is 1 + a 4-term dot product (5 roundings); b - I
and J_q a few products of F's entries (about 1, so absolute roundings of ~10 EPS);
the F-bar factor a cbrt or sqrt (LIBM) and its products, ln J (LIBM), the 4-point
weighted means and the division by J_bar (~10): about 40 roundings of the stiffness
scale lambda + 2 mu, on each of the two evaluations (this one and the code's), 2 x 40
= 80 EPS (lambda + 2 mu) (a few 1e-3 Pa). A frame one step off differs by the stress
change of one step: at the front, where a cell's strain changes by about v / c a step,
(lambda + 2 mu) v / c ~ 1e8 Pa here, eleven orders above.

A small-strain path-dependent body's frame is the points' update at the u written, from
the committed state, over the step that reached it: the update the next step commits.
Oracle (exact equivalence): under steps that change, a viscoplastic J2 body (whose
return reads the step, eta / h) gives a frame's point stresses equal, bit for bit, to
those the next step commits at the same u (the same kernel on the same numbers). Over
the step before, h_{n-1/2} instead of h_{n+1/2}, they differ at every flowing point.
"""
import math
import os

import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics import cli
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.integrator import Integrator
from impact_fenics.materials.j2 import J2
from impact_fenics.quad_meshes import one_body
from impact_fenics.stepping import StepSequence
from impact_fenics.xdmf import FieldSeries
from roundoff import EPS
from scene_texts import ROOT, replace

COMM = MPI.COMM_WORLD
E, NU = 200e9, 0.3
LMBDA, MU = E * NU / ((1 + NU) * (1 - 2 * NU)), E / (2 * (1 + NU))
TOL = 80 * EPS * (LMBDA + 2 * MU)  # Pa: the module's docstring

AXISYMMETRIC = f"""title = "neo-Hookean bar on the wall"
[mesh]
generator = "quad_bar"
radius = 0.004
length = 0.02
n_r = 2

[materials.steel]
model = "neo_hookean"
E = {E!r}
nu = {NU!r}
density = 7850.0

[bodies.bar]
material = "steel"
velocity = [0.0, -20.0]
strain = "finite"

[wall]
z = 0.0
method = "film"

[time]
t_end = 3e-6
cfl = 0.5
dt_interval = 10

[output]
output_every = 3
"""


def _plane_strain() -> str:
    with open(os.path.join(ROOT, "scenes", "plane_strain_finite_wall.toml")) as f:
        text = f.read()
    text = replace(text, "nu = 0.0 ", f"nu = {NU!r} ")
    text = replace(text, "t_end = 2.5e-5", "t_end = 4.5e-6")
    text = replace(text, "output_every = 20", "output_every = 3")
    return replace(text, 'dir = "results/plane_strain_finite_wall"\n', "")


G = 1.0 / math.sqrt(3.0)
POINTS = ((-G, -G), (G, -G), (G, G), (-G, G))


def closed_form(X: np.ndarray, U: np.ndarray, plane: bool) -> np.ndarray:
    """Cauchy stress (m, 4) (Pa) in (rr, tt, zz, rz) (xx, out, yy, xy) of neo-Hookean Q1
    F-bar cells with reference nodes X (m, 4, 2) going round the cell and displacements
    U (m, 4, 2) (m)."""
    m = X.shape[0]
    w, J, F2, Ftt = np.empty((4, m)), np.empty((4, m)), np.empty((4, m, 2, 2)), np.empty((4, m))
    for q, (xi, eta) in enumerate(POINTS):
        N = 0.25 * np.array([(1 - xi) * (1 - eta), (1 + xi) * (1 - eta),
                             (1 + xi) * (1 + eta), (1 - xi) * (1 + eta)])
        dN = 0.25 * np.array([[-(1 - eta), 1 - eta, 1 + eta, -(1 + eta)],
                              [-(1 - xi), -(1 + xi), 1 + xi, 1 - xi]])
        jac = np.einsum("ik,mkj->mij", dN, X)  # dX_j / dxi_i
        dNdX = np.linalg.solve(jac, np.broadcast_to(dN, (m, 2, 4)))  # (m, 2, 4)
        F2[q] = np.eye(2) + np.einsum("mka,mbk->mab", U, dNdX)
        R = X[:, :, 0] @ N
        w[q] = np.abs(np.linalg.det(jac)) * (1.0 if plane else R)
        Ftt[q] = 1.0 if plane else 1.0 + (U[:, :, 0] @ N) / R
        J[q] = np.linalg.det(F2[q]) * Ftt[q]
    volume = w.sum(axis=0)
    jbar = (w * J).sum(axis=0) / volume
    tau_mean = np.zeros((m, 4))
    for q in range(4):
        alpha = np.sqrt(jbar / J[q]) if plane else np.cbrt(jbar / J[q])
        Fb = alpha[:, None, None] * F2[q]
        ftt = np.ones(m) if plane else alpha * Ftt[q]
        b = Fb @ np.swapaxes(Fb, 1, 2)
        vol = LMBDA * np.log(jbar)
        tau = np.stack([MU * (b[:, 0, 0] - 1) + vol, MU * (ftt * ftt - 1) + vol,
                        MU * (b[:, 1, 1] - 1) + vol, MU * b[:, 0, 1]], axis=1)
        tau_mean += w[q][:, None] * tau
    return tau_mean / (volume * jbar)[:, None]


def _run(tmp_path_factory, text: str, name: str) -> FieldSeries:
    base = COMM.bcast(str(tmp_path_factory.mktemp(name)), root=0)
    scene = os.path.join(base, "scene.toml")
    if COMM.rank == 0:
        with open(scene, "w") as f:
            f.write(text)
    COMM.barrier()
    out = os.path.join(base, "run")
    assert cli.main(["run", scene, "--out", out, "--quiet"]) == 0
    return FieldSeries(os.path.join(out, "fields.xdmf"))


@pytest.mark.parametrize("geometry", ["axisymmetric", "plane_strain"])
def test_a_frames_stress_is_that_of_its_displacement(tmp_path_factory, geometry):
    plane = geometry == "plane_strain"
    series = _run(tmp_path_factory, _plane_strain() if plane else AXISYMMETRIC, geometry)
    names = (("sigma_xx", "sigma_out", "sigma_yy", "sigma_xy") if plane else
             ("sigma_rr", "sigma_tt", "sigma_zz", "sigma_rz"))
    X = series.points[series.cells]
    worst, largest = 0.0, 0.0
    for k in range(1, len(series.times)):
        U = series.values("displacement", k)[:, :2][series.cells]
        expected = closed_form(X, U, plane)
        written = np.stack([series.values(n, k) for n in names], axis=1)
        worst = max(worst, float(np.abs(written - expected).max()))
        largest = max(largest, float(np.abs(expected).max()))
    # the frames saw the impact (stresses far above the tolerance), and each is its u's
    assert largest > 1e6 * TOL
    assert worst <= TOL, (worst, TOL, largest)


def test_a_small_strain_frame_is_the_update_the_next_step_commits():
    """A viscoplastic J2 disc (4 x 10 mm, P1 triangles, 1 mm) at 20 m/s onto its held face
    z = 0 (rho c v ~ 9e8 Pa against a 200 MPa yield: the points at the face flow), under
    steps alternating between 0.3 and 0.15 of h / c every two steps; at every change of
    step the frame's point stresses at u^{n+1} against the next step's committed ones."""
    from dolfinx import mesh as dmesh

    mesh = dmesh.create_rectangle(COMM, [np.array([0.0, 0.0]), np.array([4e-3, 10e-3])],
                                  [4, 10], cell_type=dmesh.CellType.triangle)
    # eta / h ~ 1e4 / 1e-8 = 1e12 Pa, above 3 mu = 2.3e11: the step changes the return
    j2 = J2(E=200e9, nu=0.3, density=7850.0, yield_stress=200e6, hardening=5e9,
            viscosity=1e4)
    model = DeformableModel(one_body(mesh), [Body("body", j2)])
    owned = model.n_owned // 2
    face = np.flatnonzero(np.abs(model.node_xy[:owned, 1]) <= 1e-12)
    fixed = np.concatenate([model.axis_dofs(), 2 * face + 1]).astype(np.int32)
    h_c = 1e-3 / math.sqrt(E / 7850.0)  # s: a cell's transit at the bar speed
    steps = [f * h_c for f in (0.3, 0.3, 0.15, 0.15) * 6]
    integ = Integrator(model, None, fixed, policy=StepSequence(steps))
    v0 = np.zeros(model.n_owned)
    v0[1::2] = -20.0
    integ.set_initial(None, v0)
    force, u = integ.nonlinear[0], integ.u_function.x
    frame, compared, flowing = None, 0, 0
    for n in range(len(steps) - 1):
        eps_before = force.qs.eps_p.copy()
        integ.predict()  # the update at u^n, committed
        if frame is not None:
            assert np.array_equal(force.qs.sigma, frame)
            compared += 1
            flowing += int(np.any(force.qs.eps_p != eps_before))
        integ.advance()
        frame = None
        if n >= 1 and steps[n] != steps[n - 1]:  # u^{n+1} reached by another step:
            # the points' last update took h_{n-1/2}, this frame's and the next one's h_{n+1/2}
            u.scatter_forward()
            frame = force.point_stresses(u.array).sigma.copy()
    compared, flowing = COMM.allreduce(compared), COMM.allreduce(flowing)
    assert compared >= 5 * COMM.size and flowing >= 1
