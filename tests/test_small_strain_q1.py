"""Small strain on bilinear quadrilaterals (Q1) with mean dilatation (B-bar).

Oracles that do not come from the code under test:

* the patch test: on a distorted axisymmetric patch (cells on the axis and off it) the
  linear field u_r = a r, u_z = b z + c (the linear fields that carry a constant stress
  in equilibrium without body force in axisymmetry: a constant shear would need one,
  d sigma_rz / dr + sigma_rz / r = sigma_rz / r) gives the exact constant stress at
  every point, no force at interior nodes and, at boundary nodes, the consistent nodal
  force of the traction sigma n on the straight sides, to round-off; for the assembled
  K and for the path-dependent kernel (J2 in its elastic range);
* the assembled B-bar K times u equals the kernel's internal force for an elastic
  material, to round-off, and K is symmetric;
* the nu = 0 bar against d'Alembert, with the tolerances of the triangles' wave test;
* the thick-walled cylinder at nu = 0.499 against Lame: B-bar converges as h^2, a fully
  integrated Q1 locks;
* small-strain Q1 J2 against finite-strain Q1 J2 (the same element, F-bar) at low
  strain: they differ by O(strain);
* the element bound on omega_max is an upper bound of the converged omega_max;
* a whole run (Simulation) of a J2 bar on Q1: the ledger closes to round-off and no
  cell stress leaves the yield surface.

Every check runs unchanged on any number of ranks.
"""
import math
import os

import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh as dmesh
from mpi4py import MPI
from petsc4py import PETSc

from roundoff import rounding

from impact_fenics import compat, q1
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.cell_fields import CellStress
from impact_fenics.errors import InputError
from impact_fenics.quad_meshes import quad_bar
from impact_fenics.forms import stiffness_form, traction_form
from impact_fenics.integrator import Integrator
from impact_fenics.internal_force.finite import FiniteStrainForce
from impact_fenics.internal_force.quadrature import QuadPointGeometry, QuadratureForce
from impact_fenics.loads import SurfaceLoad, Trapezoid
from impact_fenics.materials import LinearElastic
from impact_fenics.materials.finite_j2 import FiniteJ2
from impact_fenics.materials.j2 import J2
from impact_fenics.operators import assemble_owned, assemble_stiffness, elastic_stiffness, lumped_mass
from impact_fenics.probes import arrival_time
from impact_fenics.quad_meshes import quad_rectangle, tag_rectangle
from impact_fenics.stability import converged_omega_max, critical_dt, element_omega_bound

COMM = MPI.COMM_WORLD
E, NU, RHO = 200e9, 0.3, 7850.0


# ------------------------------------------------------------------ helpers
def distorted_patch(r0: float, n: int = 4, amplitude: float = 0.25):
    """n x n quadrilaterals on r0 <= r <= r0 + 1, 0 <= z <= 1 (m), interior nodes moved by
    up to ``amplitude`` cell sides in a smooth pattern of their coordinates (the same on
    every rank), sides kept straight: an arbitrary, untwisted patch."""
    tm = quad_rectangle(COMM, r0, 0.0, r0 + 1.0, 1.0, n, n, "patch")
    x = tm.mesh.geometry.x
    h = 1.0 / n
    tol = 1e-9 * h
    inner = ((x[:, 0] > r0 + tol) & (x[:, 0] < r0 + 1.0 - tol)
             & (x[:, 1] > tol) & (x[:, 1] < 1.0 - tol))
    r, z = x[inner, 0].copy(), x[inner, 1].copy()
    x[inner, 0] += amplitude * h * np.sin(7.1 * r + 3.3 * z)
    x[inner, 1] += amplitude * h * np.cos(5.3 * r - 2.9 * z)
    return tm


def linear_field(model, a: float, b: float, c: float) -> fem.Function:
    """u_r = a r, u_z = b z + c (m) at every local node (owned and ghost)."""
    u = fem.Function(model.V)
    xy = model.node_xy
    u.x.array[0::2] = a * xy[:, 0]
    u.x.array[1::2] = b * xy[:, 1] + c
    return u


def exact_stress(a: float, b: float, D: np.ndarray) -> np.ndarray:
    """sigma = D eps (Pa) of the constant strain (a, a, b, 0)."""
    return D @ np.array([a, a, b, 0.0])


def traction_forces(model, sigma: np.ndarray) -> np.ndarray:
    """Owned nodal forces (N) of the traction sigma n of a constant stress on the patch's
    sides: int t . w 2 pi r ds, by dolfinx on the facets (exact: r N_a is quadratic on
    a straight side, the rule's degree 2 integrates it)."""
    f = np.zeros(model.n_owned)
    tm = model.tmesh
    for side, comp, value in (("outer", 0, sigma[0]), ("inner", 0, -sigma[0]),
                              ("top", 1, sigma[2]), ("bottom", 1, -sigma[2])):
        if side not in tm.facet_names:
            continue  # the axis carries no force (r = 0)
        t = (value, 0.0) if comp == 0 else (0.0, value)
        f += assemble_owned(model, traction_form(model.V, tm.facet_tags, tm.facet_tag(side),
                                                   model.geometry, t))
    return f


def node_force_scale(model, geometry, stress_max: float) -> np.ndarray:
    """Per owned dof: sum over the points of its cells of w_q (|dN/dr| + |N / r| + |dN/dz|)
    times the largest stress, the sum of the |terms| of its force (N)."""
    g = geometry
    terms = g.w[:, :, None] * (np.abs(g.dNdr) + np.abs(g.N[None] * g.inv_r[:, :, None])
                               + np.abs(g.dNdz))
    per_node = np.zeros(model.node_xy.shape[0])
    np.add.at(per_node, g.dofs.ravel(), terms.sum(axis=1).ravel() * stress_max)
    fn = fem.Function(model.V)
    fn.x.array[0::2] = per_node
    fn.x.array[1::2] = per_node
    compat.scatter_add(fn.x)
    return fn.x.array[: model.n_owned].copy()


def interior_dofs(model) -> np.ndarray:
    """Owned dofs of nodes on no side of the patch (their force must vanish)."""
    boundary = np.zeros(model.n_owned, dtype=bool)
    for side in model.tmesh.facet_names:
        for comp in (0, 1):
            boundary[model.facet_dofs(side, comp)] = True
    return np.flatnonzero(~boundary)


def allmax(x) -> float:
    return COMM.allreduce(float(np.max(np.abs(x), initial=0.0)), op=MPI.MAX)


# ------------------------------------------------------------------ the patch test
PATCH_FIELD = (1e-4, -2e-4, 3e-5)  # a, b (-), c (m): stresses ~ 50 MPa, elastic for J2


@pytest.mark.parametrize("r0", [0.0, 0.5])
@pytest.mark.parametrize("kind", ["linear", "j2"])
def test_patch(r0, kind):
    """A distorted patch touching the axis (r0 = 0) and one off it (r0 = 0.5 m): the
    linear field gives the exact constant stress at every point (kernel) and in every
    cell (the run's cell stress output), and the exact nodal forces (K u and the
    kernel's force): zero inside, the traction's on the sides."""
    tm = distorted_patch(r0)
    material = (LinearElastic(E=E, nu=NU, density=RHO) if kind == "linear"
                else J2(E=E, nu=NU, density=RHO, yield_stress=250e6, hardening=1e9))
    model = DeformableModel(tm, [Body("patch", material)])
    a, b, c = PATCH_FIELD
    u = linear_field(model, a, b, c)
    D = elastic_stiffness(material)
    sigma = exact_stress(a, b, D)
    s_max = float(np.abs(sigma).max())
    if kind == "linear":
        K = assemble_stiffness(model)
        Ku = K.createVecLeft()
        K.mult(compat.petsc_vec(u), Ku)
        f = Ku.array.copy()
        geometry = QuadPointGeometry(model, model.owned_cells("patch"))
    else:
        force = QuadratureForce(model, "patch", u, 1e-7, np.zeros(model.n_owned))
        f = force.compute().copy()
        geometry = force.geometry
        # every point: the exact stress, elastic (no plastic strain)
        assert allmax(force.qs.eps_p) == 0.0
    # u -> eps_q: 4 products and 3 sums per component on terms up to |grad N| |u|; the
    # B-bar shift and D add about 10 roundings: 32 roundings of the strain scale times the
    # largest row of D, rounded up; a cell's weighted mean of 4 points adds 8
    u_max = allmax(u.x.array)
    g_max = max(allmax(geometry.dNdr), allmax(geometry.dNdz), allmax(geometry.inv_r))
    strain_scale = 4 * g_max * u_max * float(np.abs(D).sum(axis=1).max())
    if kind == "j2":
        assert allmax(force.qs.sigma - sigma) <= rounding(32, strain_scale)
    # the cell stress of the outputs (linear: D times the mean strain; path-dependent: the
    # weighted mean of the points' stresses)
    cell_tol = rounding(32 + 8, strain_scale)
    cells = CellStress(model, [] if kind == "linear" else [force]).evaluate(u.x.array)
    exact_rows = np.array([sigma[0], sigma[2], sigma[1], sigma[3]])  # STRESS_NAMES order
    assert allmax(cells[:4] - exact_rows[:, None]) <= cell_tol
    # the nodal forces: per dof a sum of up to 4 cells x 4 points x 3 terms (48 roundings)
    # each carrying ~16 of its own (strain, stress, B-bar mean, weight): 64 roundings of
    # the sum of the |terms| (N); 2 more for the traction's own assembly
    scale = node_force_scale(model, geometry, s_max)
    bound = rounding(64 + 2, scale)
    expected = traction_forces(model, sigma)
    inside = interior_dofs(model)
    assert COMM.allreduce(inside.size) > 0
    assert COMM.allreduce(int(np.sum(np.abs(f[inside]) > bound[inside]))) == 0
    assert COMM.allreduce(int(np.sum(np.abs(f - expected) > bound))) == 0
    # the oracle is not empty: the boundary forces are far above the bound
    assert allmax(expected) > 1e6 * allmax(bound)


# ------------------------------------------------------------------ K u = the kernel's force
def test_assembled_bbar_stiffness_is_the_kernels_force():
    """On the distorted patch touching the axis, an arbitrary smooth displacement: K u
    (K assembled once from the B-bar element matrices) equals the fused kernel's force
    for the same elastic material (J2 that never yields) to round-off; K is symmetric,
    in both matrix formats."""
    tm = distorted_patch(0.0)
    j2 = J2(E=E, nu=NU, density=RHO, yield_stress=1e300)
    model = DeformableModel(tm, [Body("patch", j2)])
    u = fem.Function(model.V)
    xy = model.node_xy
    u.x.array[0::2] = 1e-4 * np.sin(3.0 * xy[:, 0] + xy[:, 1]) * xy[:, 0]  # u_r = 0 on the axis
    u.x.array[1::2] = 1e-4 * np.cos(2.0 * xy[:, 1] - xy[:, 0])
    force = QuadratureForce(model, "patch", u, 1e-7, np.zeros(model.n_owned))
    f = force.compute().copy()
    # the bound per row: K u sums 18 products, each entry of K carries ~100 roundings (4
    # points, B-bar rows, 8 x 4 products), the kernel's force ~20 per term over 48 terms:
    # 256 roundings of the row's sum of |K_ij u_j| bound the two paths' difference
    K = assemble_stiffness(model, "aij")
    ia, ja, va = K.getValuesCSR()
    u_glob = np.concatenate(COMM.allgather(u.x.array[: model.n_owned]))
    row_scale = np.array([np.abs(va[ia[i]:ia[i + 1]] * u_glob[ja[ia[i]:ia[i + 1]]]).sum()
                          for i in range(ia.size - 1)])
    K.destroy()
    for matrix_type in ("aij", "baij"):
        K = assemble_stiffness(model, matrix_type)
        Ku = K.createVecLeft()
        K.mult(compat.petsc_vec(u), Ku)
        assert COMM.allreduce(int(np.sum(np.abs(Ku.array - f) > rounding(256, row_scale)))) == 0
        assert allmax(f) > 1e10 * allmax(rounding(256, row_scale))  # not an empty check
        if matrix_type == "aij":  # (PETSc checks symmetry of AIJ only)
            assert K.isSymmetric(rounding(64, K.norm(PETSc.NormType.INFINITY)))
        K.destroy()
        Ku.destroy()


def test_linear_and_path_dependent_bodies_share_a_q1_mesh():
    """Two bodies on one distorted Q1 patch (cells below z = 1/2 linear elastic, above it
    J2 that never yields, the same E and nu): the linear bodies' K (assembled over their
    cells only) times u plus the path-dependent body's force equals K of both bodies
    times u, to round-off (the bound of the test above)."""
    from impact_fenics.meshing import TaggedMesh

    base = distorted_patch(0.0)
    mesh = base.mesh
    cmap = mesh.topology.index_map(2)
    cells = np.arange(cmap.size_local + cmap.num_ghosts, dtype=np.int32)
    x = mesh.geometry.x
    centre_z = x[compat.geometry_dofs(mesh)[cells], 1].mean(axis=1)
    tags = np.where(centre_z < 0.5, 1, 2).astype(np.int32)
    cell_tags = dmesh.meshtags(mesh, 2, cells, tags)
    tm = TaggedMesh(mesh, cell_tags, base.facet_tags, {"lower": 1, "upper": 2},
                    base.facet_names)
    bodies = [Body("lower", LinearElastic(E=E, nu=NU, density=RHO)),
              Body("upper", J2(E=E, nu=NU, density=RHO, yield_stress=1e300))]
    model = DeformableModel(tm, bodies)
    u = fem.Function(model.V)
    xy = model.node_xy
    u.x.array[0::2] = 1e-4 * np.sin(3.0 * xy[:, 0] + xy[:, 1]) * xy[:, 0]
    u.x.array[1::2] = 1e-4 * np.cos(2.0 * xy[:, 1] - xy[:, 0])
    f = QuadratureForce(model, "upper", u, 1e-7, np.zeros(model.n_owned)).compute().copy()
    results = []
    for parts in ([model.parts[0]], None):  # the linear body's K, then both bodies'
        K = assemble_stiffness(model, "aij", parts)
        Ku = K.createVecLeft()
        K.mult(compat.petsc_vec(u), Ku)
        results.append(Ku.array.copy())
        if parts is None:
            ia, ja, va = K.getValuesCSR()
            u_glob = np.concatenate(COMM.allgather(u.x.array[: model.n_owned]))
            row_scale = np.array([np.abs(va[ia[i]:ia[i + 1]] * u_glob[ja[ia[i]:ia[i + 1]]]).sum()
                                  for i in range(ia.size - 1)])
        K.destroy()
        Ku.destroy()
    assert COMM.allreduce(int(np.sum(tags == 1))) > 0 and COMM.allreduce(int(np.sum(tags == 2))) > 0
    both = results[0] + f
    assert COMM.allreduce(int(np.sum(np.abs(both - results[1]) > rounding(256, row_scale)))) == 0


# ------------------------------------------------------------------ stable step
def test_element_bound_is_above_the_converged_omega():
    """On the distorted patch (axis fixed): the element bound on omega_max (B-bar element
    matrices, Gauss-point masses) is at least the converged omega_max of M^-1 K (the
    Rayleigh quotient of an assembled sum of elements is below the largest element one);
    SLEPc's relative tolerance 1e-10 is the only slack."""
    tm = distorted_patch(0.0)
    model = DeformableModel(tm, [Body("patch", LinearElastic(E=E, nu=NU, density=RHO))])
    K = assemble_stiffness(model)
    mass = lumped_mass(model)
    bound = element_omega_bound(model, model.axis_dofs(owned=False))
    converged = converged_omega_max(K, mass, model.to_global(model.axis_dofs()))
    if COMM.rank == 0:
        print(f"Q1 B-bar omega: element bound {bound:.6g}, converged {converged:.6g} rad/s")
    assert bound >= converged * (1.0 - 1e-9)
    # the lumped mass is the ring volume times rho: pi ((r0+1)^2 - r0^2) * 1 m * rho, with
    # 2x2 Gauss exact on the cells; one sum over the nodes (256 roundings of the total)
    total = COMM.allreduce(float(mass[0::2].sum()))
    assert abs(total - RHO * math.pi) <= rounding(256, RHO * math.pi)
    assert COMM.allreduce(int(np.sum(mass <= 0.0))) == 0


# ------------------------------------------------------------------ the nu = 0 wave
P0 = 100e6  # Pa
T_RISE, T_FALL, T_PULSE_END = 2e-5, 1e-4, 1.2e-4  # s (the triangles' wave test)
T_END = 1.5e-4  # s
STATIONS = (0.3, 0.6)  # z (m) of the two probes, at r = 0.02 m
PROBE_R = 0.02


def probe_cell(model, point) -> tuple[int, np.ndarray]:
    """The owned cell whose centroid is nearest to ``point`` (one rank's, -1 elsewhere)
    and its centroid (m, on every rank)."""
    cells = model.owned_cells("bar")
    dofs = compat.cell_dofs(model.V)[cells]
    centroids = model.node_xy[dofs].mean(axis=1)
    d = np.hypot(centroids[:, 0] - point[0], centroids[:, 1] - point[1])
    k = int(np.argmin(d)) if d.size else -1
    best, rank = COMM.allreduce((float(d[k]) if k >= 0 else np.inf, COMM.rank), op=MPI.MINLOC)
    mine = COMM.rank == rank
    c = COMM.bcast(centroids[k] if mine else None, root=rank)
    return (k if mine else -1), c


def wave_run(h: float, kind: str) -> dict:
    """The nu = 0 steel bar (radius 0.05 m, length 1 m, quad_bar's n_r x n_z cells of side
    h) under the trapezoid pressure on z = 0, u_r = 0 on the axis, dt = 0.9 x the element
    bound; sigma_zz and u_z of the two probe cells (cell means) every step."""
    n_r, n_z = round(0.05 / h), round(1.0 / h)
    tm = tag_rectangle(quad_bar(COMM, 0.05, 1.0, n_r, n_z), "bar")
    material = (LinearElastic(E=E, nu=0.0, density=RHO) if kind == "linear"
                else J2(E=E, nu=0.0, density=RHO, yield_stress=1e300))
    model = DeformableModel(tm, [Body("bar", material)])
    dt = 0.9 * critical_dt(element_omega_bound(model, model.axis_dofs(owned=False)))
    load = SurfaceLoad(model, "bottom", Trapezoid(P0, T_RISE, T_FALL, T_PULSE_END))
    integ = Integrator(model, dt, model.axis_dofs(), loads=[load])
    probes = [probe_cell(model, (PROBE_R, z)) for z in STATIONS]
    cells = model.owned_cells("bar")
    geo = [QuadPointGeometry(model, cells[[k]]) if k >= 0 else None for k, _ in probes]
    D = elastic_stiffness(material)
    n_steps = int(math.ceil(T_END / dt))
    hist = np.zeros((n_steps, 1 + 2 * len(probes)))
    eps = np.zeros((1, 4))
    u_local = fem.Function(model.V)
    for n in range(n_steps):
        t = integ.t
        u_local.x.array[: model.n_owned] = integ.u_owned
        u_local.x.scatter_forward()
        integ.predict()  # the path-dependent force updates its points at u^n here
        integ.advance()
        hist[n, 0] = t
        for i, ((k, _), g) in enumerate(zip(probes, geo)):
            if k < 0:
                continue
            if kind == "linear":
                q1.mean_strain(g.dofs, g.dNdr, g.dNdz, g.N, g.inv_r, g.w, u_local.x.array, eps)
                s_zz = float((D @ eps[0])[2])
            else:
                f = integ.nonlinear[0]
                s_zz = float(f.qs.sigma[k, :, 2] @ f.geometry.w[k] / f.geometry.w[k].sum())
            hist[n, 1 + 2 * i] = s_zz
            hist[n, 2 + 2 * i] = float(u_local.x.array[2 * g.dofs[0] + 1].mean())
    hist[:, 1:] = COMM.allreduce(hist[:, 1:], op=MPI.SUM)  # one rank holds each probe
    t = hist[:, 0]
    c0 = math.sqrt(E / RHO)
    z = [c[1] for _, c in probes]
    arrivals = [arrival_time(t, -hist[:, 1 + 2 * i], 0.5 * P0) for i in range(2)]
    window = (t > arrivals[0] + 3e-5) & (t < arrivals[0] + 7e-5)
    return {"c0": c0, "z": z, "arrivals": arrivals,
            "speed": (z[1] - z[0]) / (arrivals[1] - arrivals[0]),
            "stress": float(np.mean(hist[window, 1])),
            "velocity": float(np.polyfit(t[window], hist[window, 2], 1)[0]), "dt": dt}


@pytest.fixture(scope="module")
def waves():
    return {(h, kind): wave_run(h, kind) for h in (0.01, 0.005) for kind in ("linear", "j2")}


@pytest.mark.parametrize("kind", ["linear", "j2"])
@pytest.mark.parametrize("h", [0.01, 0.005])
def test_wave_against_dalembert(waves, h, kind):
    """The tolerances of the triangles' wave test (tests/test_wave.py): arrival of the
    ramp's half level within one element transit time h / c0 of z / c0 + t_rise / 2; the
    speed between the probes within h / (their distance); plateau stress and velocity
    within (h / l)^2, l = c0 t_rise = 0.1 m the ramp's length (the dispersion ringing
    behind the ramp), sigma = -rho c0 v within twice that."""
    s = waves[(h, kind)]
    c0 = s["c0"]
    if COMM.rank == 0:
        print(f"Q1 {kind} h = {h}: speed {s['speed']:.1f} vs c0 {c0:.1f} m/s, plateau "
              f"{s['stress'] / 1e6:.3f} MPa, v {s['velocity']:.5f} m/s")
    for z, t in zip(s["z"], s["arrivals"]):
        assert abs(t - (z / c0 + T_RISE / 2)) <= h / c0
    assert abs(s["speed"] - c0) / c0 <= h / (s["z"][1] - s["z"][0])
    tol = (h / 0.1) ** 2
    v_exact = P0 / (RHO * c0)
    assert abs(s["stress"] + P0) <= tol * P0
    assert abs(s["velocity"] - v_exact) <= tol * v_exact
    assert abs(s["stress"] + RHO * c0 * s["velocity"]) <= 2 * tol * P0


def test_wave_speed_error_shrinks_with_h(waves):
    for kind in ("linear", "j2"):
        e = [abs(waves[(h, kind)]["speed"] / waves[(h, kind)]["c0"] - 1) for h in (0.01, 0.005)]
        assert e[1] < e[0]


def test_wave_kernel_equals_linear_path(waves):
    """The elastic J2 (the B-bar kernel) and the linear body (K u) are one operator: their
    probe histories agree far below the discretisation tolerances (round-off that the
    steps carry along: 1e-9 of the plateau is 10^6 times the one-step round-off)."""
    for h in (0.01, 0.005):
        a, b = waves[(h, "linear")], waves[(h, "j2")]
        assert abs(a["stress"] - b["stress"]) <= 1e-9 * P0
        assert abs(a["velocity"] - b["velocity"]) <= 1e-9 * a["velocity"]


# ------------------------------------------------------------------ the thick cylinder
A_IN, B_OUT, P_IN, E_CYL, NU_CYL = 0.1, 0.2, 1e6, 1e9, 0.499


def lame_radial(r: float) -> float:
    """Lame's u_r(r) (m) in plane strain under the internal pressure P_IN."""
    return ((1 + NU_CYL) * P_IN * A_IN ** 2 / (E_CYL * (B_OUT ** 2 - A_IN ** 2))
            * ((1 - 2 * NU_CYL) * r + B_OUT ** 2 / r))


def cylinder_error(n: int, full_integration: bool) -> float:
    """Largest relative error of u_r on r = a: n x n cells through the wall (a slice of
    height b - a), u_z = 0 on its top and bottom (plane strain), the static solve
    K u = f with K assembled once (B-bar, or the fully integrated UFL form on Q1)."""
    tm = quad_rectangle(COMM, A_IN, 0.0, B_OUT, B_OUT - A_IN, n, n, "wall")
    model = DeformableModel(tm, [Body("wall", LinearElastic(E=E_CYL, nu=NU_CYL, density=1e3))])
    if full_integration:  # 2x2 Gauss on every term, the volumetric one included
        K = fem.petsc.assemble_matrix(compat.compile_form(stiffness_form(model.V, model.parts, model.geometry)))
        K.assemble()
    else:
        K = assemble_stiffness(model)
    f = assemble_owned(model, traction_form(model.V, tm.facet_tags, tm.facet_tag("inner"), model.geometry))
    fixed = model.to_global(np.concatenate([model.facet_dofs("bottom", 1),
                                            model.facet_dofs("top", 1)]))
    b = K.createVecLeft()
    b.array[:] = P_IN * f
    x = K.createVecRight()
    x.set(0.0)
    A = K.copy()
    A.zeroRowsColumns(fixed.astype(PETSc.IntType), 1.0, x, b)
    ksp = PETSc.KSP().create(COMM)
    ksp.setOperators(A)
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    ksp.getPC().setFactorSolverType("mumps")
    ksp.solve(b, x)
    inner = model.facet_dofs("inner", 0)
    err = allmax(x.array[inner] / lame_radial(A_IN) - 1.0)
    for obj in (ksp, A, K, b, x):
        obj.destroy()
    return err


def test_thick_cylinder_bbar_converges_full_integration_locks():
    """nu = 0.499, n = 4 and 8 cells through the wall. B-bar: error below 2 % and 1 %,
    falling as h^2 (by more than 3 when h halves); the fully integrated Q1 locks: its
    error is above 25 % on both meshes, more than ten times B-bar's."""
    bbar = [cylinder_error(n, False) for n in (4, 8)]
    full = [cylinder_error(n, True) for n in (4, 8)]
    if COMM.rank == 0:
        print(f"thick cylinder nu = 0.499, u_r(a) relative error: B-bar {bbar}, full {full}")
    assert bbar[0] < 2e-2 and bbar[1] < 1e-2
    assert bbar[1] < bbar[0] / 3
    assert min(full) > 0.25 and min(full) > 10 * max(bbar)


# ------------------------------------------------------------------ small vs finite strain
@pytest.mark.parametrize("strain", [2e-4, 4e-4])
def test_small_strain_j2_is_finite_strain_j2_at_low_strain(strain):
    """One cell (r in [0.5, 1] m, z in [0, 0.5] m), the homogeneous path u_r = strain / 2 r,
    u_z = -strain z in 20 steps, J2 yielding at a fifth of it (E = 200 GPa, sigma_y0 =
    E strain / 5, H = E / 100): small-strain Q1 (B-bar, additive J2) against finite-strain
    Q1 (F-bar, multiplicative J2 with Hencky elasticity, the same constants).

    They differ by the strain measure: each log stretch differs from the linear strain
    by at most x^2 / (2 (1 - |x|)), x <= strain, and the return mappings are Lipschitz
    in the strain with the elastic constants, so the stresses (Cauchy = tau / J) differ by
    at most |D|_inf strain^2 / (2 (1 - strain)) + |sigma| |1/J - 1|: relative to a stress
    of order E strain, O(strain). The nodal forces add F^-T and 1 / F_tt in P = J sigma
    F^-T (entries within strain / (1 - strain) of the identity's, twice that with J):
    per dof at most sum_q w_q |B_q| (the stress bound + 2 strain |sigma|)."""
    tm = quad_rectangle(COMM, 0.5, 0.0, 1.0, 0.5, 1, 1, "cell")
    sy = E * strain / 5
    small_mat = J2(E=E, nu=NU, density=RHO, yield_stress=sy, hardening=E / 100)
    finite_mat = FiniteJ2(E=E, nu=NU, density=RHO, yield_stress=sy, hardening=E / 100)
    model = DeformableModel(tm, [Body("cell", small_mat)])
    u = fem.Function(model.V)
    small = QuadratureForce(model, "cell", u, 1e-7, np.zeros(model.n_owned))
    finite = FiniteStrainForce(model.V, model.node_xy, model.owned_cells("cell"), finite_mat, u,
                               model.geometry)
    xy = model.node_xy
    for k in range(1, 21):
        e = strain * k / 20
        u.x.array[0::2] = 0.5 * e * xy[:, 0]
        u.x.array[1::2] = -e * xy[:, 1]
        f_small = small.compute().copy()
        f_finite = finite.compute(1e-7).copy()
    J = (1 + 0.5 * strain) ** 2 * (1 - strain)
    s_small, s_finite = small.qs.sigma, finite.tau / J
    assert COMM.allreduce(small.qs.state[..., 0].size) == 4  # one cell, four points
    assert allmax(small.qs.state[..., 0]) > strain / 2  # well past yield
    s_max = allmax(s_small)
    D = elastic_stiffness(small_mat)
    ds_bound = (np.abs(D).sum(axis=1).max() * strain ** 2 / (2 * (1 - strain))
                + s_max * abs(1 / J - 1))
    d_s = allmax(s_small - s_finite)
    f_bound = node_force_scale(model, small.geometry, ds_bound + 2 * strain * s_max)
    d_f, f_max = allmax(f_small - f_finite), allmax(f_small)  # (collectives: on every rank)
    if COMM.rank == 0:
        print(f"strain {strain}: stresses differ by {d_s / s_max:.3g} of the largest "
              f"({d_s / ds_bound:.2f} of the bound), forces by {d_f / f_max:.3g} of the largest")
    assert d_s <= ds_bound
    assert COMM.allreduce(int(np.sum(np.abs(f_small - f_finite) > f_bound))) == 0


# ------------------------------------------------------------------ refusals
def test_generic_path_and_non_constant_linear_material_refused_on_quadrilaterals():
    tm = quad_rectangle(COMM, 0.0, 0.0, 1.0, 1.0, 2, 2, "b")
    model = DeformableModel(tm, [Body("b", J2(E=E, nu=NU, density=RHO))])
    u = fem.Function(model.V)
    with pytest.raises(InputError, match="triangles only"):
        QuadratureForce(model, "b", u, 1e-7, np.zeros(model.n_owned), path="generic")

    class Graded:  # a linear material whose stress depends on the position
        density, linear = RHO, True

        def stress(self, eps):
            r = ufl.SpatialCoordinate(tm.mesh)[0]
            return (1 + r) * E * eps

        def wave_speed(self):
            return 1.0

    with pytest.raises(InputError, match="constant map of the strain"):
        DeformableModel(tm, [Body("b", Graded())])


# ------------------------------------------------------------------ a whole run
def test_simulation_runs_a_q1_plastic_bar(tmp_path):
    """A Simulation of a J2 bar on Q1 (no hardening) under a 500 MPa pressure pulse (above the
    uniaxial-strain yield sigma_y (1 - nu) / (1 - 2 nu) = 437 MPa), 200
    steps, fields written: the ledger (kinetic + stored + plastic work = load work)
    closes to the round-off of a ledger (tests/roundoff.py), the points yielded, and
    the largest cell von Mises stress of the run (the weighted mean of the points' stresses,
    each on the yield surface or inside it, a convex set) is at most sigma_y, to the
    round-off of the mean (16 roundings of sigma_y)."""
    from roundoff import ledger
    from impact_fenics.simulation import Settings, Simulation

    out = COMM.bcast(str(tmp_path / "q1_run"), root=0)
    tm = tag_rectangle(quad_bar(COMM, 0.05, 0.3, 5, 30), "bar")
    sy = 250e6
    model = DeformableModel(tm, [Body("bar", J2(E=E, nu=NU, density=RHO, yield_stress=sy))])
    pulse = Trapezoid(500e6, 1e-5, 3e-5, 4e-5)
    sim = Simulation(model, Settings(cfl=0.9, n_steps=200, output_every=50, out=out,
                                     quiet=True, plots=False),
                     fixed=[model.axis_dofs()], loads=[SurfaceLoad(model, "bottom", pulse)])
    summary = sim.run()
    if COMM.rank == 0:
        print(f"Q1 J2 bar: balance error {summary['energy_balance_error_rel']:.3g}, eps_p_max "
              f"{summary['eps_p_max']:.3g}, peak von Mises {summary['peak_stress']['von_mises']:.6g} Pa")
    assert summary["energy_balance_error_rel"] <= ledger(200, summary["n_dofs"])
    assert summary["eps_p_max"] > 0.0
    assert summary["peak_stress"]["von_mises"] <= sy * (1 + rounding(16))
    assert COMM.bcast(os.path.isfile(os.path.join(out, "fields.xdmf")) if COMM.rank == 0
                      else None, root=0)
