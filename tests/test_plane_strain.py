"""Linear plane strain (docs/plane_strain.md, migration step 1) against its oracles.

* Patch tests, P1 and Q1: a linear displacement u = A x (a uniform strain) gives in every
  cell the exact plane-strain stresses, sigma = lambda tr(eps) I + 2 mu eps with
  eps_out = 0 (so sigma_out = lambda (eps_xx + eps_yy)), and K u vanishes at every node
  not on the boundary (the interior is in equilibrium under a uniform stress). Round-off:
  a cell's stress is a few tens of products of numbers of the size of the largest stress,
  so 64 eps of it; K u's row is some 18 products of |K| |u|.
* The lumped mass sums to rho t A (kg): the row sums of the consistent mass, integrated
  exactly; round-off n eps of it over n cells.
* Invariance in t: every integral carries the factor t, so a power-of-two t scales K, M and
  the load vectors exactly (a product by 2^k rounds nothing) and a run's displacements are
  equal bit for bit; t = 0.01 gives them to round-off.
* The 1D-equivalent strip: on rollers (u_x = 0 on both sides, nu = 0.25), or with free
  sides at nu = 0, a y-only field is an exact solution of the plane-strain continuum: a
  pressure ramp p(t) on y = 0 travels at c = sqrt(M / rho) (M = lambda + 2 mu on rollers, E
  at nu = 0) with sigma_yy = -p, v_y = p / (rho c), sigma_xx = sigma_out = nu / (1 - nu)
  sigma_yy on rollers (d'Alembert's solution). Tolerances from the discretisation, as the
  axisymmetric bar's (tests/test_wave.py): the arrival of the half level within one
  element transit h / c, the plateaus within (h / l)^2, l = c t_rise the ramp's length.
* The element bound of the stable step is at least the converged omega_max (SLEPc).
* The geometry's refusals (one line each) and its names in the scene file.

Every test runs unchanged on 1, 2 and 3 ranks (sums are collective).
"""
import math
from dataclasses import replace

import numpy as np
import pytest
from mpi4py import MPI
from petsc4py import PETSc
from dolfinx import fem

from impact_fenics import loads, meshing
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.cell_fields import STRESS_NAMES, CellStress
from impact_fenics.errors import InputError
from impact_fenics.geometry import PLANE_STRAIN, Geometry
from impact_fenics.materials import LinearElastic
from impact_fenics.operators import assemble_owned, assemble_stiffness, lumped_mass
from impact_fenics.forms import traction_form
from impact_fenics.simulation import Settings, Simulation
from impact_fenics.stability import converged_omega_max, element_omega_bound

EPS = np.finfo(float).eps
STEEL = LinearElastic(E=200e9, nu=0.25, density=7850.0)
WIDTH, HEIGHT = 0.02, 0.06


def plane(t: float = 0.01) -> Geometry:
    return Geometry(PLANE_STRAIN, t)


@pytest.fixture(scope="module", params=["P1", "Q1"])
def block(request):
    """A block 0.02 x 0.06 m of triangles or quadrilaterals (h = 5 mm)."""
    return meshing.block(WIDTH, HEIGHT, h=0.005, quadrilaterals=request.param == "Q1",
                         comm=MPI.COMM_WORLD)


@pytest.fixture(scope="module", params=["P1", "Q1"])
def centred(request):
    """The block moved to x in [-0.01, 0.01] m: plane strain has no axis, and a cell's
    x may be 0 or negative (the axisymmetric hoop term would divide by it)."""
    tmesh = meshing.block(WIDTH, HEIGHT, h=0.005, quadrilaterals=request.param == "Q1",
                          comm=MPI.COMM_WORLD)
    tmesh.mesh.geometry.x[:, 0] -= 0.5 * WIDTH
    return tmesh


def model_of(tmesh, t: float = 0.01, material=STEEL) -> DeformableModel:
    return DeformableModel(tmesh, [Body("block", material)], geometry=plane(t))


def linear_field(model) -> fem.Function:
    """u = (1e-3 x + 2e-3 y, -3e-3 x + 4e-3 y) (m)."""
    u = fem.Function(model.V)
    u.interpolate(lambda x: np.vstack([1e-3 * x[0] + 2e-3 * x[1],
                                       -3e-3 * x[0] + 4e-3 * x[1]]))
    u.x.scatter_forward()
    return u


def test_patch_stresses(centred):
    model = model_of(centred)
    u = linear_field(model)
    values = CellStress(model).evaluate(u.x.array)
    lam, mu = STEEL.lmbda, STEEL.mu
    exx, eyy, exy = 1e-3, 4e-3, 0.5 * (2e-3 - 3e-3)
    exact = {"sigma_rr": lam * (exx + eyy) + 2 * mu * exx,
             "sigma_zz": lam * (exx + eyy) + 2 * mu * eyy,
             "sigma_tt": lam * (exx + eyy),  # sigma_out: eps_out = 0
             "sigma_rz": 2 * mu * exy}
    s = np.array([exact["sigma_rr"], exact["sigma_tt"], exact["sigma_zz"]])
    dev = s - s.mean()
    exact["von_mises"] = math.sqrt(1.5 * (dev @ dev + 2 * exact["sigma_rz"] ** 2))
    scale = max(abs(v) for v in exact.values())
    for k, name in enumerate(STRESS_NAMES):
        err = float(np.max(np.abs(values[k] - exact[name]))) if values.shape[1] else 0.0
        err = MPI.COMM_WORLD.allreduce(err, op=MPI.MAX)
        print(f"{model.geometry.public(name)}: exact {exact[name]:.6g} Pa, "
              f"largest error {err:.3g} Pa")
        assert err <= 64 * EPS * scale


def test_patch_equilibrium(centred):
    """K u = 0 at the interior nodes under a uniform strain."""
    model = model_of(centred)
    u = linear_field(model)
    K = assemble_stiffness(model)
    x = K.createVecRight()
    x.array[:] = u.x.array[: model.n_owned]
    f = K.createVecLeft()
    K.mult(x, f)
    xy = model.node_xy[: model.n_owned // 2]
    inside = ((np.abs(xy[:, 0]) < 0.5 * WIDTH - 1e-9)
              & (xy[:, 1] > 1e-9) & (xy[:, 1] < HEIGHT - 1e-9))
    rows = np.repeat(inside, 2)
    K_max = K.norm(PETSc.NormType.INFINITY)
    u_max = MPI.COMM_WORLD.allreduce(float(np.abs(u.x.array).max()), op=MPI.MAX)
    err = MPI.COMM_WORLD.allreduce(float(np.abs(f.array[rows]).max(initial=0.0)), op=MPI.MAX)
    print(f"interior |K u| <= {err:.3g} N against |K| |u| = {K_max * u_max:.3g} N")
    assert MPI.COMM_WORLD.allreduce(int(rows.sum())) > 0
    assert err <= 18 * 8 * EPS * K_max * u_max


def test_mass_is_rho_t_area(block):
    t = 0.01
    model = model_of(block, t)
    m = lumped_mass(model)
    total = MPI.COMM_WORLD.allreduce(float(m[1::2].sum()))
    exact = STEEL.density * t * WIDTH * HEIGHT
    n_cells = MPI.COMM_WORLD.allreduce(model.mesh.topology.index_map(2).size_local)
    print(f"sum of the lumped mass {total!r} kg, rho t A = {exact!r} kg")
    assert abs(total - exact) <= n_cells * EPS * exact
    assert np.array_equal(m[0::2], m[1::2])


def test_operators_scale_exactly_with_a_power_of_two_t(block):
    """K, M and a traction's load vector with t = 1/4 are 1/4 of those with t = 1, bit for
    bit (the factor t multiplies every point's weight; a product by 2^-2 rounds nothing)."""
    one, quarter = model_of(block, 1.0), model_of(block, 0.25)
    for op in (lambda m: lumped_mass(m),
               lambda m: assemble_owned(m, traction_form(
                   m.V, m.tmesh.facet_tags, m.tmesh.facet_tag("bottom"), m.geometry)),
               lambda m: assemble_stiffness(m).getValuesCSR()[2]):
        a, b = op(one), op(quarter)
        assert np.array_equal(0.25 * a, b)


def strip(tmesh, t: float, peak: float, rollers: bool, material, settings: Settings,
          probes=()) -> Simulation:
    model = model_of(tmesh, t, material)
    fixed = ([model.facet_dofs(side, 0) for side in ("left", "right")] if rollers else [])
    pulse = loads.Trapezoid(peak=peak, t_rise=RISE, t_fall=1.0, t_end=2.0)
    sim = Simulation(model, settings, fixed=fixed, loads=[loads.SurfaceLoad(model, "bottom",
                                                                            pulse)])
    for name, point, quantity in probes:
        sim.add_probe(name, point, quantity)
    return sim


def test_runs_scale_with_t(block):
    """The same strip with t = 1/4 and t = 1: equal displacements bit for bit, the work of
    the loads and the energies scaled by exactly 1/4; with t = 0.01 equal to round-off."""
    runs = {}
    for t in (1.0, 0.25, 0.01):
        settings = Settings(dt=2e-7, n_steps=60, out=None, quiet=True, energy_every=10)
        sim = strip(block, t, 1e7, True, STEEL, settings,
                    [("uy", (0.01, 0.0), "u_y"), ("syy", (0.01, 0.01), "sigma_yy")])
        sim.run()
        runs[t] = sim
    u = {t: runs[t].integrator.u_vec.array.copy() for t in runs}
    u1 = u[1.0]
    assert np.array_equal(u1, u[0.25])
    scale = MPI.COMM_WORLD.allreduce(float(np.abs(u1).max()), op=MPI.MAX)
    err = MPI.COMM_WORLD.allreduce(float(np.abs(u1 - u[0.01]).max()), op=MPI.MAX)
    # the t = 0.01 run rounds each of its weights once more: a relative 1e-13 covers that
    # round-off through 60 steps of some 20 products a dof
    print(f"t = 0.01: largest difference {err:.3g} m of {scale:.3g} m")
    assert err <= 1e-13 * scale
    h1, hq = runs[1.0].history.data(), runs[0.25].history.data()
    assert np.array_equal(h1["uy"], hq["uy"]) and np.array_equal(h1["syy"], hq["syy"])
    e1, eq = runs[1.0].energy.data(), runs[0.25].energy.data()
    for key in ("kinetic", "strain", "external_work"):
        assert np.array_equal(0.25 * np.asarray(e1[key]), np.asarray(eq[key])), key


RISE = 1.8e-5  # s: the ramp's rise, l = c t_rise ~ 0.1 m
H_STRIP = 0.005  # m


@pytest.fixture(scope="module", params=[("P1", 0.25, True), ("Q1", 0.25, True),
                                        ("P1", 0.0, False), ("Q1", 0.0, False)],
                ids=["P1-rollers", "Q1-rollers", "P1-nu0-free", "Q1-nu0-free"])
def wave(request):
    kind, nu, rollers = request.param
    tmesh = meshing.block(0.02, 0.5, h=H_STRIP, quadrilaterals=kind == "Q1",
                          comm=MPI.COMM_WORLD)
    material = replace(STEEL, nu=nu)
    M = material.E if nu == 0.0 else material.lmbda + 2 * material.mu
    c = math.sqrt(M / material.density)
    settings = Settings(cfl=0.9, t_end=0.4 / c + RISE, out=None, quiet=True)
    probes = []
    for k, y in enumerate((0.15, 0.3)):
        probes += [(f"syy{k}", (0.0101, y), "sigma_yy"), (f"sxx{k}", (0.0101, y), "sigma_xx"),
                   (f"sout{k}", (0.0101, y), "sigma_out"), (f"uy{k}", (0.0101, y), "u_y")]
    sim = strip(tmesh, 0.01, 1e7, rollers, material, settings, probes)
    sim.run()
    return sim, material, c, nu


def test_one_dimensional_wave(wave):
    from impact_fenics.probes import arrival_time

    sim, material, c, nu = wave
    h = sim.history.data()
    t = h["time"]
    p = 1e7
    tol = (H_STRIP / (c * RISE)) ** 2
    for k, y in enumerate((0.15, 0.3)):
        arrival = arrival_time(t, -h[f"syy{k}"] / p, 0.5)
        print(f"y = {y} m: arrival {arrival * 1e6:.3f} us, exact {(y / c + RISE / 2) * 1e6:.3f}")
        assert abs(arrival - (y / c + RISE / 2)) <= H_STRIP / c
        window = (t > y / c + RISE + 0.5e-5) & (t < t[-1])
        syy = float(np.mean(h[f"syy{k}"][window]))
        ratio = nu / (1 - nu)
        sxx = float(np.mean(h[f"sxx{k}"][window]))
        sout = float(np.mean(h[f"sout{k}"][window]))
        # v_y from u_y's slope over the window: p / (rho c)
        tw, uw = t[window], h[f"uy{k}"][window]
        v = float(np.polyfit(tw, uw, 1)[0])
        v_exact = p / (material.density * c)
        print(f"y = {y} m: sigma_yy {syy:.6g} (exact {-p:.6g}), sigma_xx {sxx:.6g}, sigma_out "
              f"{sout:.6g} (exact {-ratio * p:.6g}), v_y {v:.6g} (exact {v_exact:.6g}) m/s, "
              f"tolerance {tol:.3g}")
        assert abs(syy + p) <= tol * p
        if nu > 0:  # on rollers; at nu = 0 with free sides both are 0 to the ringing
            assert abs(sxx + ratio * p) <= tol * p
            assert abs(sout + ratio * p) <= tol * p
        else:
            assert abs(sxx) <= tol * p and abs(sout) <= tol * p
        assert abs(v - v_exact) <= tol * v_exact


def test_element_bound_holds(block):
    """2 / (element bound) <= 2 / omega_max: the bound is at least the converged omega_max
    (to SLEPc's tolerance, 1e-10 of it)."""
    model = model_of(block)
    bound = element_omega_bound(model, np.zeros(0, dtype=np.int32))
    omega = converged_omega_max(assemble_stiffness(model), lumped_mass(model),
                                np.zeros(0, dtype=np.int32))
    print(f"element bound {bound:.6g} rad/s, converged omega_max {omega:.6g} rad/s")
    assert bound >= omega * (1 - 1e-10)


def test_no_axis_dofs_and_the_symmetry_plane(block):
    model = model_of(block)
    assert MPI.COMM_WORLD.allreduce(model.axis_dofs().size) == 0
    half = DeformableModel(block, [Body("block", STEEL)],
                           geometry=Geometry(PLANE_STRAIN, 0.01, "x=0"))
    held = half.axis_dofs()
    assert np.all(held % 2 == 0)
    assert np.all(np.abs(half.node_xy[held // 2, 0]) <= 1e-12)
    n_left = MPI.COMM_WORLD.allreduce(held.size)
    assert n_left == round(HEIGHT / 0.005) + 1


@pytest.mark.parametrize("args, expected", [
    ((PLANE_STRAIN, 0.0), "thickness = 0.0: must be finite and > 0"),
    ((PLANE_STRAIN, math.inf), "thickness = inf: must be finite and > 0"),
    (("axisymmetric", 0.5), "an axisymmetric geometry has no thickness"),
    (("plane_stress",), "geometry = 'plane_stress': use one of"),
    ((PLANE_STRAIN, 1.0, "y=0"), "symmetry = 'y=0': use one of x=0"),
])
def test_geometry_refuses(args, expected):
    with pytest.raises(InputError, match=expected.replace("(", r"\(")):
        Geometry(*args)


def test_half_model_equals_the_full_one():
    """A half model x in [0, w] with symmetry = "x=0" against the full block x in [-w, w]
    under the same pressure ramp on y = 0 (free sides; Q1, whose grid is mirror symmetric):
    at every node of the half the same displacement, to round-off; the full model's mass
    twice the half's. The round-off: the full model's u_x on x = 0 is a sum of mirror
    contributions that cancel only to some 18 products' rounding a step, which reaches u as
    dt^2 / m f <= 4 |u| (omega dt <= 2) times 18 eps, through the velocity into the
    displacement, so growing as n^2 / 2 over n steps: 36 n^2 eps of the largest u."""
    comm = MPI.COMM_WORLD
    half_mesh = meshing.block(WIDTH, HEIGHT, h=0.005, quadrilaterals=True, comm=comm)
    full_mesh = meshing.block(2 * WIDTH, HEIGHT, h=0.005, quadrilaterals=True, comm=comm)
    full_mesh.mesh.geometry.x[:, 0] -= WIDTH
    runs = {}
    for name, tmesh, symmetry in (("half", half_mesh, "x=0"), ("full", full_mesh, None)):
        model = DeformableModel(tmesh, [Body("block", STEEL)],
                                geometry=Geometry(PLANE_STRAIN, 0.01, symmetry))
        pulse = loads.Trapezoid(peak=1e7, t_rise=RISE, t_fall=1.0, t_end=2.0)
        sim = Simulation(model, Settings(dt=2e-7, n_steps=60, out=None, quiet=True),
                         loads=[loads.SurfaceLoad(model, "bottom", pulse)])
        sim.run()
        xy = model.node_xy[: model.n_owned // 2]
        u = sim.integrator.u_vec.array.reshape(-1, 2)
        nodes = comm.allgather((xy, u))
        runs[name] = (np.concatenate([a for a, _ in nodes]), np.concatenate([b for _, b in nodes]),
                      sim.body_mass["block"])
    xy_h, u_h, m_h = runs["half"]
    xy_f, u_f, m_f = runs["full"]
    key = lambda xy: np.lexsort((np.round(xy[:, 0] / 1e-6), np.round(xy[:, 1] / 1e-6)))
    right = xy_f[:, 0] >= -1e-12
    xy_f, u_f = xy_f[right], u_f[right]
    a, b = key(xy_h), key(xy_f)
    assert np.allclose(xy_h[a], xy_f[b], rtol=0, atol=1e-12)
    scale = float(np.abs(u_f).max())
    err = float(np.abs(u_h[a] - u_f[b]).max())
    print(f"half against full: largest difference {err:.3g} m of {scale:.3g} m; masses "
          f"{m_h!r}, {m_f!r} kg")
    assert err <= 36 * 60 ** 2 * EPS * scale
    assert abs(m_f - 2 * m_h) <= 64 * EPS * m_f
