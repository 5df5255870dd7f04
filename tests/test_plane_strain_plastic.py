"""Path-dependent small strain in plane strain (docs/plane_strain.md, migration step 2)
against its oracles, on P1 (one point per cell) and Q1 (B-bar, 2x2 points).

* The elastic range: a J2 body that never yields and a Drucker-Prager rock far inside its
  cone, under an arbitrary smooth displacement of a block that straddles x = 0 (plane
  strain has no axis): the fused kernel's force equals K u of the linear plane-strain
  stiffness (the UFL forms of step 1, another code path) to round-off; under a uniform
  strain every point's stress is the plane-strain Hooke's law, sigma_out = lambda tr eps.
  Round-off: each entry of K u and of the kernel's force is a sum of products whose
  roundings (K: ~100 per entry from its points and rows; the kernel: ~20 per term) stay
  within 256 of the row's sum of |K_ij u_j|, as the axisymmetric B-bar test bounds them.
* The J2 block: a homogeneous strain ramp eps(s) = s D with a fixed in-plane direction D
  (normal and shear parts, eps_out = 0), applied at every node, driven through yield to
  ten times the yield strain. The closed form of proportional loading with linear
  hardening H: e = dev eps, e_eq = sqrt(2/3 e : e), elastic while 3 G e_eq <= sigma_y0,
  then eps_bar_p = (3 G e_eq - sigma_y0) / (3 G + H), q = sigma_y0 + H eps_bar_p,
  s = 2 G e q / (3 G e_eq), sigma = K tr(eps) I + s (sigma_out = K tr eps + s_out, not
  lambda tr eps once yielded) and eps_p = 3/2 eps_bar_p s / q, whose out-of-plane
  component grows. The return is exact along a fixed direction (radial return of a
  proportional path), so every increment matches to round-off: a point's stress is some
  50 operations on numbers of the size of the largest stress, 64 EPS of it per increment,
  the plastic strain carrying every earlier increment's roundings forward (64 k EPS at
  the k-th).
* Pure shear eps_xy = gamma / 2 in plane strain yields at gamma = sigma_y0 / (sqrt 3 G)
  and, perfectly plastic, flows at sigma_xy = sigma_y0 / sqrt 3 with sigma_out = 0
  (a special case of the above, stated for the reader).

* Locking: the plane-strain thick cylinder, a quarter annulus a <= r <= b (symmetry planes
  x = 0 and y = 0 held), J2 perfectly plastic at nu = 0.4999, driven quasi-statically by
  the radial displacement U of its inner wall to twice U_L = k b^2 / (2 G a) (Hill's
  collapse, k = sigma_y / sqrt 3): the reaction pressure reaches the limit
  p_L = (2 / sqrt 3) sigma_y ln(b / a) (Hill, The Mathematical Theory of Plasticity,
  ch. V; it holds for every nu: at collapse the flow is deviatoric with eps_out = 0). The
  mesh is the rectangle (r, phi) of n x 2n cells mapped onto the annulus: Q1, and P1 on the
  block's alternating diagonals. A locking element's collapse load does not converge to p_L
  (the incompressible flow is over-constrained on every mesh); a sound one's error falls
  with h: halving h at least halves it (first order; B-bar and the constant-strain triangle
  are second order on this smooth flow). On the plateau (U_L to 2 U_L) the pressure is
  stationary up to Hill's O(1 - 2 nu) lag of a compressible material. Each increment is
  solved by the elastic-stiffness iteration K du = -R(u) of the axisymmetric limit test
  (tests/test_q1_limit_pressure.py), the pressure read as the inner wall's radial reaction
  over the polygon's t a m sin(dphi) (the radial sum of a uniform pressure on its m chords).

Every test runs unchanged on 1, 2 and 3 ranks (sums and maxima are collective).
"""
import math

import numpy as np
import pytest
from mpi4py import MPI
from petsc4py import PETSc
from dolfinx import fem

from roundoff import rounding

from impact_fenics import compat, meshing
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.geometry import PLANE_STRAIN, Geometry
from impact_fenics.internal_force.quadrature import QuadratureForce
from impact_fenics.materials.drucker_prager import DruckerPrager
from impact_fenics.materials.j2 import J2
from impact_fenics.operators import assemble_stiffness
from impact_fenics.quad_meshes import quad_rectangle

COMM = MPI.COMM_WORLD
EPS = np.finfo(float).eps
E, NU, RHO = 200e9, 0.3, 7850.0
WIDTH, HEIGHT, T = 0.02, 0.03, 0.01


def allmax(x) -> float:
    return COMM.allreduce(float(np.max(np.abs(x), initial=0.0)), op=MPI.MAX)


@pytest.fixture(scope="module", params=["P1", "Q1"])
def centred(request):
    """A block 0.02 x 0.03 m (h = 5 mm) moved to x in [-0.01, 0.01] m, of triangles or
    quadrilaterals."""
    tmesh = meshing.block(WIDTH, HEIGHT, h=0.005, quadrilaterals=request.param == "Q1",
                          comm=COMM)
    tmesh.mesh.geometry.x[:, 0] -= 0.5 * WIDTH
    return tmesh


def model_of(tmesh, material) -> DeformableModel:
    return DeformableModel(tmesh, [Body("block", material)],
                           geometry=Geometry(PLANE_STRAIN, T))


def force_of(model, u) -> QuadratureForce:
    return QuadratureForce(model, "block", u, 1e-7, np.zeros(model.n_owned))


ELASTIC_RANGE = {
    "J2": J2(E=E, nu=NU, density=RHO, yield_stress=1e300),
    # stresses of ~1e8 Pa far inside a cone of intercept ~1e15 Pa and cut-off 1e12 Pa
    "DruckerPrager": DruckerPrager(E=E, nu=NU, density=RHO, ucs=1e15, tensile_strength=1e12),
}


@pytest.mark.parametrize("name", sorted(ELASTIC_RANGE))
def test_elastic_range_force_is_K_u(centred, name):
    model = model_of(centred, ELASTIC_RANGE[name])
    u = fem.Function(model.V)
    xy = model.node_xy
    u.x.array[0::2] = 1e-4 * np.sin(3.0 * xy[:, 0] + xy[:, 1])
    u.x.array[1::2] = 1e-4 * np.cos(2.0 * xy[:, 1] - xy[:, 0])
    force = force_of(model, u)
    f = force.compute().copy()
    assert force.qs.eps_p.shape[1] == (4 if model.quadrilateral else 1)  # points per cell
    K = assemble_stiffness(model, "aij")
    ia, ja, va = K.getValuesCSR()
    u_glob = np.concatenate(COMM.allgather(u.x.array[: model.n_owned]))
    row_scale = np.array([np.abs(va[ia[i]:ia[i + 1]] * u_glob[ja[ia[i]:ia[i + 1]]]).sum()
                          for i in range(ia.size - 1)])
    Ku = K.createVecLeft()
    K.mult(compat.petsc_vec(u), Ku)
    err = allmax(Ku.array - f)
    print(f"{name}: |K u - f_kernel| <= {err:.3g} N, |f| = {allmax(f):.3g} N")
    assert COMM.allreduce(int(np.sum(np.abs(Ku.array - f) > rounding(256, row_scale)))) == 0
    assert allmax(f) > 1e10 * allmax(rounding(256, row_scale))  # not an empty check
    K.destroy()
    Ku.destroy()


@pytest.mark.parametrize("name", sorted(ELASTIC_RANGE))
def test_elastic_range_patch_stresses(centred, name):
    """u = A x: every point's stress is Hooke's in plane strain, sigma_out = lambda tr eps."""
    material = ELASTIC_RANGE[name]
    model = model_of(centred, material)
    u = fem.Function(model.V)
    u.interpolate(lambda x: np.vstack([1e-4 * x[0] + 2e-4 * x[1], -3e-4 * x[0] + 4e-4 * x[1]]))
    u.x.scatter_forward()
    force = force_of(model, u)
    force.compute()
    lam, mu = material.lmbda, material.mu
    exx, eyy, exy = 1e-4, 4e-4, 0.5 * (2e-4 - 3e-4)
    exact = np.array([lam * (exx + eyy) + 2 * mu * exx, lam * (exx + eyy),
                      lam * (exx + eyy) + 2 * mu * eyy, 2 * mu * exy])
    err = allmax(force.qs.sigma - exact)
    print(f"{name}: (sigma_xx, sigma_out, sigma_yy, sigma_xy) = {exact} Pa, error {err:.3g} Pa")
    assert err <= 64 * EPS * np.abs(exact).max()
    assert allmax(force.qs.eps_p) == 0.0


def proportional(D: np.ndarray, s: float, material: J2) -> tuple[np.ndarray, np.ndarray, float]:
    """The closed form of J2 under eps = s D (xx, out, yy, xy; tensor shear; eps_out = 0):
    the stress (Pa), the plastic strain and the equivalent plastic strain (see the module)."""
    G, K = material.mu, material.lmbda + 2.0 * material.mu / 3.0
    sy, H = material.yield_stress, material.hardening
    eps = s * D
    tr = eps[0] + eps[1] + eps[2]
    e = eps - tr / 3.0 * np.array([1.0, 1.0, 1.0, 0.0])
    e_eq = math.sqrt(2.0 / 3.0 * (e[0] ** 2 + e[1] ** 2 + e[2] ** 2 + 2.0 * e[3] ** 2))
    dev, ebar = 2.0 * G * e, 0.0
    if 3.0 * G * e_eq > sy:
        ebar = (3.0 * G * e_eq - sy) / (3.0 * G + H)
        dev *= (sy + H * ebar) / (3.0 * G * e_eq)
    q = math.sqrt(1.5 * (dev[0] ** 2 + dev[1] ** 2 + dev[2] ** 2 + 2.0 * dev[3] ** 2))
    sigma = dev + K * tr * np.array([1.0, 1.0, 1.0, 0.0])
    eps_p = 1.5 * ebar * dev / q if ebar > 0.0 else np.zeros(4)
    return sigma, eps_p, ebar


@pytest.mark.parametrize("direction, hardening", [
    ((0.5, -1.0, 0.3), 2e9),   # in-plane normal and shear parts, hardening
    ((0.0, 0.0, 0.5), 0.0),    # pure shear eps_xy = gamma / 2, perfectly plastic
])
def test_j2_block_follows_the_closed_form(centred, direction, hardening):
    j2 = J2(E=E, nu=NU, density=RHO, yield_stress=250e6, hardening=hardening)
    model = model_of(centred, j2)
    dxx, dyy, dxy = direction
    D = np.array([dxx, 0.0, dyy, dxy])  # (xx, out, yy, xy): eps_out = 0
    u = fem.Function(model.V)
    force = force_of(model, u)
    xy = model.node_xy
    # the yield strain along D: 3 G e_eq(s D) = sigma_y0
    e = D - (D[0] + D[2]) / 3.0 * np.array([1.0, 1.0, 1.0, 0.0])
    s_yield = j2.yield_stress / (3.0 * j2.mu * math.sqrt(
        2.0 / 3.0 * (e[0] ** 2 + e[1] ** 2 + e[2] ** 2 + 2.0 * e[3] ** 2)))
    worst = 0.0
    for k in range(1, 41):  # to ten times the yield strain in 40 increments
        s = 10.0 * s_yield * k / 40
        u.x.array[0::2] = s * (dxx * xy[:, 0] + dxy * xy[:, 1])
        u.x.array[1::2] = s * (dxy * xy[:, 0] + dyy * xy[:, 1])
        force.compute()
        sigma, eps_p, ebar = proportional(D, s, j2)
        scale = np.abs(sigma).max()
        err = allmax(force.qs.sigma - sigma)
        worst = max(worst, err / scale)
        # the plastic strain carries every increment's roundings forward: 64 EPS each
        assert err <= 64 * k * EPS * scale, f"increment {k}: stress off by {err:.3g} Pa"
        assert allmax(force.qs.eps_p - eps_p) <= 64 * k * EPS * max(ebar, s_yield)
        assert allmax(force.qs.state[..., 0] - ebar) <= 64 * k * EPS * max(ebar, s_yield)
    print(f"D = {direction}, H = {hardening:g} Pa: at 10 eps_y sigma = {sigma} Pa, "
          f"eps_bar_p = {ebar:.4g}, eps_p_out = {eps_p[1]:.4g}; largest relative error {worst:.3g}")
    assert ebar > 0.0  # it has flowed past yield
    if dxx == dyy == 0.0 and hardening == 0.0:  # pure shear, perfectly plastic
        assert abs(sigma[3] - j2.yield_stress / math.sqrt(3.0)) <= 64 * EPS * j2.yield_stress
        assert sigma[1] == 0.0 and eps_p[1] == 0.0
    else:  # sigma_out follows the flow: neither lambda tr eps nor 0, eps_p_out grows
        lam_tr = j2.lmbda * s * (dxx + dyy)
        assert abs(sigma[1] - lam_tr) > 1e-3 * scale and abs(eps_p[1]) > 1e-3 * ebar


def test_the_generic_path_is_refused_in_plane_strain():
    tmesh = meshing.block(WIDTH, HEIGHT, h=0.005, comm=COMM)
    model = model_of(tmesh, ELASTIC_RANGE["J2"])
    u = fem.Function(model.V)
    from impact_fenics.errors import InputError

    with pytest.raises(InputError, match="runs axisymmetric triangles only"):
        QuadratureForce(model, "block", u, 1e-7, np.zeros(model.n_owned), path="generic")


# ------------------------------------------------------------------ locking: the thick cylinder
A_IN, B_OUT, SY = 0.1, 0.2, 1e6  # m, m, Pa
P_LIMIT = 2.0 / math.sqrt(3.0) * SY * math.log(B_OUT / A_IN)
NU_INCOMPRESSIBLE = 0.4999
RES, MAX_ITERATIONS = 1e-10, 200


def annulus(n: int, quadrilaterals: bool):
    """The quarter annulus of n cells through the wall and 2n round it: (tagged mesh, its
    facet names (inner wall, y = 0, x = 0), the number of chords of the inner wall)."""
    m, W = 2 * n, B_OUT - A_IN
    if quadrilaterals:
        tm = quad_rectangle(COMM, A_IN, 0.0, B_OUT, 1.0, n, m, "wall")
        names = ("inner", "bottom", "top")
        x = tm.mesh.geometry.x
        r, phi = x[:, 0].copy(), x[:, 1] * (0.5 * math.pi)
    else:
        tm = meshing.block(W, 2.0 * W, h=W / n, comm=COMM)
        names = ("left", "bottom", "top")
        x = tm.mesh.geometry.x
        r, phi = A_IN + x[:, 0], x[:, 1] / (2.0 * W) * (0.5 * math.pi)
    x[:, 0], x[:, 1] = r * np.cos(phi), r * np.sin(phi)
    return tm, names, m


def collapse(n: int, quadrilaterals: bool, n_increments: int = 40) -> np.ndarray:
    """The reaction pressure (Pa) at U_k = 2 U_L k / n_increments, k = 1..n_increments."""
    tm, (inner, bottom, top), m = annulus(n, quadrilaterals)
    j2 = J2(E=1e9, nu=NU_INCOMPRESSIBLE, density=1e3, yield_stress=SY)
    body = "wall" if quadrilaterals else "block"  # the generators' cell groups
    model = DeformableModel(tm, [Body(body, j2)], geometry=Geometry(PLANE_STRAIN, T))
    u = fem.Function(model.V)
    n_owned = model.n_owned
    force = QuadratureForce(model, body, u, 1.0, np.zeros(n_owned))
    qs = force.qs
    ix, iy = model.facet_dofs(inner, 0), model.facet_dofs(inner, 1)
    cos, sin = model.node_xy[ix // 2, 0] / A_IN, model.node_xy[iy // 2, 1] / A_IN
    held = np.unique(np.concatenate([ix, iy, model.facet_dofs(bottom, 1),
                                     model.facet_dofs(top, 0)]))
    K = assemble_stiffness(model)
    K.zeroRowsColumns(model.to_global(held).astype(PETSc.IntType), 1.0)
    ksp = PETSc.KSP().create(COMM)
    ksp.setOperators(K)
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    ksp.getPC().setFactorSolverType("mumps")
    rhs, du = K.createVecLeft(), K.createVecRight()
    U_L = SY / math.sqrt(3.0) * B_OUT ** 2 / (2.0 * j2.mu * A_IN)
    chords = T * A_IN * m * math.sin(0.5 * math.pi / m)
    committed = [a.copy() for a in (qs.eps_p, qs.state, qs.sigma)]
    pressures = []
    for k in range(1, n_increments + 1):
        U = 2.0 * U_L * k / n_increments
        u.x.array[ix], u.x.array[iy] = U * cos, U * sin
        for _ in range(MAX_ITERATIONS):
            u.x.scatter_forward()
            for a, c in zip((qs.eps_p, qs.state, qs.sigma), committed):
                a[:] = c  # every iterate returns from the last converged state
            f = force.compute()
            reaction = COMM.allreduce(float(f[ix] @ cos + f[iy] @ sin))
            R = f.copy()
            R[held] = 0.0
            if math.sqrt(COMM.allreduce(float(R @ R))) <= RES * abs(reaction):
                break
            rhs.array[:] = -R
            ksp.solve(rhs, du)
            u.x.array[:n_owned] += du.array
        else:
            raise AssertionError(f"increment {k}: the iteration did not converge")
        for a, c in zip((qs.eps_p, qs.state, qs.sigma), committed):
            c[:] = a
        pressures.append(reaction / chords)
    for obj in (ksp, K, rhs, du):
        obj.destroy()
    return np.array(pressures)


@pytest.mark.parametrize("element", ["P1", "Q1"])
def test_thick_cylinder_reaches_the_limit_pressure_without_locking(element):
    runs = {n: collapse(n, element == "Q1") for n in (4, 8)}
    errors = {n: p[-1] / P_LIMIT - 1.0 for n, p in runs.items()}
    for n, p in runs.items():
        print(f"{element}, {n} x {2 * n} cells: p / p_L at 2 U_L = {p[-1] / P_LIMIT:.6f}, "
              f"at U_L = {p[19] / P_LIMIT:.6f}")
        # the plateau: stationary from U_L on, but for Hill's O(1 - 2 nu) lag
        assert abs(p[-1] - p[19]) <= (1.0 - 2.0 * NU_INCOMPRESSIBLE) * P_LIMIT
    print(f"{element}: error ratio {errors[4] / errors[8]:.2f} as h halves")
    assert abs(errors[8]) <= 0.5 * abs(errors[4])
