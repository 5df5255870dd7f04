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

Every test runs unchanged on 1, 2 and 3 ranks (sums and maxima are collective).
"""
import math

import numpy as np
import pytest
from mpi4py import MPI
from dolfinx import fem

from roundoff import rounding

from impact_fenics import compat, meshing
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.geometry import PLANE_STRAIN, Geometry
from impact_fenics.internal_force.quadrature import QuadratureForce
from impact_fenics.materials.drucker_prager import DruckerPrager
from impact_fenics.materials.j2 import J2
from impact_fenics.operators import assemble_stiffness

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
