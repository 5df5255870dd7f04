"""Drucker-Prager matched to Mohr-Coulomb in plane strain (docs/plane_strain.md, section 4,
migration step 5) against Mohr-Coulomb's closed form.

Mohr-Coulomb in the plane (tension positive, sigma_1 >= sigma_3 the in-plane principal
stresses): (sigma_1 - sigma_3)/2 = c cos phi - (sigma_1 + sigma_3)/2 sin phi, or, with
N = (1 + sin phi)/(1 - sin phi), sigma_3 = N sigma_1 - 2 c sqrt(N). A body in plane
strain reaches it in steady flow: the stress stationary, so every strain rate plastic and
the out-of-plane one zero.

* The element: a block of P1 (one point per cell) or Q1 (B-bar) cells under a homogeneous
  biaxial strain, first an in-plane compression eps_xx = eps_yy = -e_0 (the confinement,
  elastic), then eps_yy shortened by s and eps_xx lengthened by r s with
  r = (1 + sin psi)/(1 - sin psi): the in-plane dilation -(d eps_xx + d eps_yy)/(d eps_xx -
  d eps_yy) = -sin psi of Mohr-Coulomb's flow, which the cone's steady flow has under the
  plane-strain match. The stress then settles on the cone where its flow is that
  direction, and there (sigma_xx - sigma_yy)/2 + (sigma_xx + sigma_yy)/2 sin phi = c cos phi
  for every confinement. It settles geometrically, per increment, so after 200 increments
  of the yield strain c/G the transient is far below round-off (it is at 1e-11 of c after
  100 on the slowest case, psi = 0). Round-off: the return is some 50 operations on
  stresses of at most |sigma|max, 64 EPS |sigma|max (the J2 block's bound), and the
  residual's five more.
* The point under constant confinement: sigma_xx = -p_0 held (the strain eps_xx solved at
  each increment by the secant method to round-off), eps_yy shortened:
  the axial stress reaches sigma_yy = N sigma_xx - 2 c sqrt(N), the closed form, to the
  same round-off (and N times the confinement's residual). The compression-meridian cone
  overstates it: associated (psi = phi = 30 deg) its plane-strain strength is
  Mohr-Coulomb's for the angle and cohesion that the plane-strain formulas give its slope
  and intercept (sin^2 phi' = 3 alpha^2/(9 - alpha^2), c' = k sqrt(3 + sin^2 phi') /
  (3 cos phi')), 2.8 times the axial stress at this confinement; at phi = 50 deg,
  psi = 0 its slope is beyond plane strain's bound and the axial stress grows without a
  limit.
* A scene: a strip of the matched rock on rollers under a 10 MPa pulse runs on 1, 2 and
  3 ranks, its stress inside the matched cone.
* The key: ``match`` is a word of two, refused otherwise in one line; the plane-strain
  match is refused in an axisymmetric scene and model in one line; the tension cut-off's bound uses
  the matched cone.

The point tests are serial arithmetic (the same on every rank); the element's sums and
maxima are collective: every test runs unchanged on 1, 2 and 3 ranks.
"""
import math

import numpy as np
import pytest
from mpi4py import MPI
from dolfinx import fem

from scene_texts import ROOT, assert_ranks_agree, assert_refused, launch, read_history, replace

from impact_fenics import meshing
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.errors import InputError
from impact_fenics.geometry import PLANE_STRAIN, Geometry
from impact_fenics.internal_force.quadrature import QuadratureForce
from impact_fenics.materials.drucker_prager import DruckerPrager

COMM = MPI.COMM_WORLD
EPS = np.finfo(float).eps
E, NU, RHO, UCS, P_T = 60e9, 0.25, 2600.0, 200e6, 1e6
ANGLES = [(40.0, 10.0), (50.0, 0.0), (30.0, 30.0)]  # (phi, psi) in degrees
DT = 1e-6  # s (rate-independent: unused)


def rock(phi: float, psi: float, match: str = "plane_strain") -> DruckerPrager:
    return DruckerPrager(E=E, nu=NU, density=RHO, ucs=UCS, friction_angle=phi,
                         dilatancy_angle=psi, tensile_strength=P_T, match=match)


def allmax(x) -> float:
    return COMM.allreduce(float(np.max(np.abs(x), initial=0.0)), op=MPI.MAX)


def allmin(x) -> float:
    return COMM.allreduce(float(np.min(x, initial=np.inf)), op=MPI.MIN)


@pytest.fixture(scope="module", params=["P1", "Q1"])
def block(request):
    """A block 0.02 x 0.03 m of 2 x 3 cells."""
    return meshing.block(0.02, 0.03, h=0.01, quadrilaterals=request.param == "Q1", comm=COMM)


@pytest.mark.parametrize("phi, psi", ANGLES)
def test_element_under_biaxial_strain_reaches_mohr_coulomb(block, phi, psi):
    material = rock(phi, psi)
    model = DeformableModel(block, [Body("block", material)],
                            geometry=Geometry(PLANE_STRAIN, 0.01))
    u = fem.Function(model.V)
    force = QuadratureForce(model, "block", u, DT, np.zeros(model.n_owned))
    xy = model.node_xy
    c = material.cohesion
    sin_phi, cos_phi = math.sin(math.radians(phi)), math.cos(math.radians(phi))
    r = (1.0 + math.sin(math.radians(psi))) / (1.0 - math.sin(math.radians(psi)))
    e0, ey = 6.0 * c / E, c / material.mu  # the confinement's strain, the yield strain

    def strain(exx: float, eyy: float) -> None:
        u.x.array[0::2] = exx * xy[:, 0]
        u.x.array[1::2] = eyy * xy[:, 1]
        force.compute()

    for k in range(1, 21):  # the confinement, elastic
        strain(-e0 * k / 20, -e0 * k / 20)
    assert allmax(force.qs.eps_p) == 0.0
    for k in range(1, 201):  # the biaxial path to 200 yield strains
        strain(-e0 + r * k * ey, -e0 - k * ey)
    sigma = force.qs.sigma.reshape(-1, 4)
    sxx, syy = sigma[:, 0], sigma[:, 2]
    residual = 0.5 * np.abs(sxx - syy) + 0.5 * (sxx + syy) * sin_phi - c * cos_phi
    scale = allmax(sigma)
    err = allmax(residual)
    print(f"{'Q1' if model.quadrilateral else 'P1'} phi = {phi}, psi = {psi}: "
          f"sigma_xx = {allmin(sxx):.6g}, sigma_yy = {allmin(syy):.6g} Pa, Mohr-Coulomb "
          f"residual {err:.3g} Pa = {err / c:.2g} c")
    assert err <= 64 * EPS * scale  # the return's roundings (module docstring)
    assert allmax(force.qs.state[..., 0]) > 10 * ey  # it has flowed
    assert allmin(-(sxx + syy)) > 0.0  # in compression, on the cone, not the cut-off


def confined(material: DruckerPrager, p0: float, n: int, inc: float) -> list[np.ndarray]:
    """The stress (Pa) after each of ``n`` increments of eps_yy by -inc c/G, sigma_xx = -p0
    held (eps_xx by the secant method), eps_out = eps_xy = 0; from the elastic state
    sigma_xx = sigma_yy = -p0."""
    params = material.params()
    eps_p, state, sigma = np.zeros(4), np.zeros(2), np.zeros(4)
    exx = eyy = -p0 / (2.0 * (material.lmbda + material.mu))
    step = inc * material.cohesion / material.mu

    def sxx(x: float) -> float:  # sigma_xx + p0 at eps_xx = x, the state not committed
        s = np.zeros(4)
        material.update(np.array([x, 0.0, eyy, 0.0]), eps_p.copy(), state.copy(), params, DT, s)
        return s[0] + p0

    out = []
    for _ in range(n):
        eyy -= step
        x0, x1 = exx, exx + 1e-6 * step
        f0, f1 = sxx(x0), sxx(x1)
        best = min((abs(f0), x0), (abs(f1), x1))
        for _ in range(40):  # the secant to round-off (the return is piecewise smooth)
            if f1 == 0.0 or f1 == f0:
                break
            x0, x1 = x1, x1 - f1 * (x1 - x0) / (f1 - f0)
            f0, f1 = f1, sxx(x1)
            best = min(best, (abs(f1), x1))
        exx = best[1]
        material.update(np.array([exx, 0.0, eyy, 0.0]), eps_p, state, params, DT, sigma)
        out.append(sigma.copy())
    return out


def mohr_coulomb_axial(sigma3: float, c: float, phi_rad: float) -> float:
    """sigma_1 = N sigma_3 - 2 c sqrt(N) (Pa): the axial stress (the more compressive one)
    at the Mohr-Coulomb limit under the lateral stress sigma3 (tension positive)."""
    n = (1.0 + math.sin(phi_rad)) / (1.0 - math.sin(phi_rad))
    return n * sigma3 - 2.0 * c * math.sqrt(n)


@pytest.mark.parametrize("phi, psi", ANGLES)
def test_confined_point_reaches_the_closed_form(phi, psi):
    material = rock(phi, psi)
    c = material.cohesion
    p0 = c  # confinement (Pa)
    sigma = confined(material, p0, 200, 1.0)[-1]
    exact = mohr_coulomb_axial(sigma[0], c, math.radians(phi))
    n = (1.0 + math.sin(math.radians(phi))) / (1.0 - math.sin(math.radians(phi)))
    err = abs(sigma[2] - exact)
    print(f"phi = {phi}, psi = {psi}: sigma_xx = {sigma[0]:.6g}, sigma_yy = {sigma[2]:.10g} "
          f"Pa, Mohr-Coulomb {exact:.10g} Pa, error {err / abs(exact):.2g} of it")
    # the confinement held to the return's roundings (64 EPS of the largest stress);
    # the closed form is evaluated at the sigma_xx reached, so its residual does not enter
    assert abs(sigma[0] + p0) <= 64 * EPS * abs(sigma).max()
    # the return's roundings, and the closed form's few of N sigma_xx
    assert err <= 64 * EPS * abs(sigma).max() + 4 * n * EPS * p0


def test_compression_match_overstates_plane_strain_strength():
    phi = 30.0
    c = rock(phi, phi).cohesion
    plane = confined(rock(phi, phi), c, 200, 1.0)[-1]
    compression = rock(phi, phi, "compression")
    history = confined(compression, c, 200, 1.0)
    sigma = history[-1]
    # the associated cone of slope alpha and intercept k is, in plane strain, Mohr-Coulomb
    # of sin^2 phi' = 3 alpha^2 / (9 - alpha^2), c' = k sqrt(3 + sin^2 phi') / (3 cos phi')
    alpha, k = compression.alpha_f, compression.k
    s2 = 3.0 * alpha * alpha / (9.0 - alpha * alpha)
    phi_eq = math.asin(math.sqrt(s2))
    c_eq = k * math.sqrt(3.0 + s2) / (3.0 * math.cos(phi_eq))
    exact = mohr_coulomb_axial(sigma[0], c_eq, phi_eq)
    print(f"phi = psi = 30 deg, confinement c: axial stress {plane[2]:.6g} Pa (plane-strain "
          f"match), {sigma[2]:.6g} Pa (compression match; its closed form {exact:.6g} Pa, "
          f"phi' = {math.degrees(phi_eq):.4g} deg, c' = {c_eq:.4g} Pa): "
          f"{sigma[2] / plane[2]:.3f} times")
    n_eq = (1.0 + math.sin(phi_eq)) / (1.0 - math.sin(phi_eq))
    # the return's roundings, the closed form's few of N' sigma_xx and of c' (from the
    # cone's alpha and k, each a few roundings of numbers of size c' and N')
    assert abs(sigma[2] - exact) <= 64 * EPS * abs(sigma).max() + 16 * n_eq * EPS * (c + c_eq)
    assert sigma[2] / plane[2] > 2.0
    # phi = 50, psi = 0: no plane-strain limit on the compression meridian's cone
    growing = confined(rock(50.0, 0.0, "compression"), c, 200, 1.0)
    limit = mohr_coulomb_axial(-c, rock(50.0, 0.0).cohesion, math.radians(50.0))
    print(f"phi = 50, psi = 0: compression match's axial stress {growing[99][2]:.4g} Pa at "
          f"100 c/G, {growing[-1][2]:.4g} Pa at 200 c/G; Mohr-Coulomb {limit:.4g} Pa")
    assert growing[-1][2] < 1.5 * growing[99][2] < 1.5 * 3.0 * limit


def test_the_matched_cone():
    """The slopes and intercept of the plane-strain match; psi = phi the associated one."""
    m = rock(40.0, 40.0)
    s = math.sin(math.radians(40.0))
    assert m.alpha_f == pytest.approx(3 * s / math.sqrt(3 + s * s), rel=4 * EPS)
    assert m.alpha_g == pytest.approx(m.alpha_f, rel=4 * EPS)
    assert m.k == pytest.approx(3 * m.cohesion * math.cos(math.radians(40.0))
                                / math.sqrt(3 + s * s), rel=8 * EPS)
    default = DruckerPrager(E=E, nu=NU, density=RHO)
    assert default.match == "compression"
    assert default.k == UCS * (1.0 - default.alpha_f / 3.0)


def test_bad_parameters_refused():
    with pytest.raises(InputError, match=r'material.match = .bogus.: must be one of '
                                         r'"compression", "plane_strain"'):
        rock(40.0, 10.0, "bogus")
    # the cut-off's bound is the matched cone's apex k / alpha_f
    m = rock(40.0, 10.0)
    apex = m.k / m.alpha_f
    with pytest.raises(InputError, match="tensile_strength"):
        DruckerPrager(E=E, nu=NU, density=RHO, ucs=UCS, friction_angle=40.0,
                      dilatancy_angle=10.0, tensile_strength=1.01 * apex, match="plane_strain")


def test_axisymmetric_model_refuses_the_plane_strain_match(block):
    with pytest.raises(InputError, match=r"body 'block': match = \"plane_strain\" .* needs "
                                         r"geometry = \"plane_strain\""):
        DeformableModel(block, [Body("block", rock(40.0, 10.0))])


STRIP = open(f"{ROOT}/scenes/plane_strain_strip.toml").read()
ROCK = ('[materials.steel]\nmodel = "drucker_prager"\nucs = 200e6\nfriction_angle = 40.0\n'
        'dilatancy_angle = 10.0\ntensile_strength = 1e6\n')


@pytest.mark.skipif(COMM.size > 1, reason="launches its own runs")
@pytest.mark.parametrize("axisymmetric, word, expected", [
    (True, '"plane_strain"', '[materials.steel] match = "plane_strain": the plane-strain match '
                             'to Mohr-Coulomb needs geometry = "plane_strain"'),
    (False, '"plane"', "[materials.steel] match = \"plane\": must be one of \"compression\", "
                       "\"plane_strain\""),
    (False, "1.0", "[materials.steel] match = 1.0: must be one of"),
])
def test_scene_key_refused(tmp_path, axisymmetric, word, expected):
    text = replace(STRIP, "[materials.steel]\n", ROCK + f"match = {word}\n")
    if axisymmetric:
        text = replace(replace(text, 'geometry = "plane_strain"\n', ""),
                       "thickness = 0.01        # m, the slab's thickness t\n", "")
        text = text.replace('components = ["x"]', 'components = ["r"]')
        text = text.replace('"sigma_yy"', '"sigma_zz"').replace('"sigma_out"', '"sigma_tt"')
        text = text.replace('"u_y"', '"u_z"')
    scene = tmp_path / "rock.toml"
    scene.write_text(text)
    assert_refused(["run", scene, "--out", tmp_path / "out"], "error: " + expected,
                   tmp_path / "out")


def test_scene_key_accepted(tmp_path):
    from impact_fenics.scene_file import read_scene

    scene = tmp_path / "rock.toml"
    scene.write_text(replace(STRIP, "[materials.steel]\n", ROCK + 'match = "plane_strain"\n'))
    material = read_scene(str(scene)).materials["steel"].material("small")
    assert material.match == "plane_strain"
    assert material.k == rock(40.0, 10.0).k


# the strip of rock matched in plane strain, on rollers (phi = psi = 30 deg; ucs chosen so
# that the 10 MPa load yields it: the elastic precursor's limit is about 6 MPa)
ROCK_STRIP = replace(STRIP, "[materials.steel]\n",
                     '[materials.steel]\nmodel = "drucker_prager"\nucs = 3e6\n'
                     'friction_angle = 30.0\ndilatancy_angle = 30.0\ntensile_strength = 1e5\n'
                     'match = "plane_strain"\n') + """
[[probes]]
name = "sigma_xx_mid"
point = [0.01, 0.1]
quantity = "sigma_xx"

[[probes]]
name = "eps_p_mid"
point = [0.01, 0.1]
quantity = "eps_p_eq"
"""


@pytest.mark.skipif(COMM.size > 1, reason="launches its own runs (serial and under mpirun)")
def test_rock_strip_runs_on_ranks(tmp_path):
    """The plane-strain match in a scene, on 1, 2 and 3 ranks (within 1e-10 of each
    column's largest value). At every output the mid probe's stress lies inside the cone of
    the plane-strain match, q <= alpha_f p + k with alpha_f = 3 sin phi / sqrt(3 + sin^2 phi)
    and k = 3 c cos phi / sqrt(3 + sin^2 phi) at psi = phi (section 4's formulas written
    out here), to the return's round-off (64 EPS of the stress), and it has flowed."""
    scene = tmp_path / "rock_strip.toml"
    scene.write_text(ROCK_STRIP)
    out = tmp_path / "n1"
    proc = launch(["run", scene, "--out", out, "--quiet"], timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    h = read_history(out)
    s = math.sin(math.radians(30.0))
    c = 3e6 * (1.0 - s) / (2.0 * math.cos(math.radians(30.0)))
    alpha = 3.0 * s / math.sqrt(3.0 + s * s)
    k = 3.0 * c * math.cos(math.radians(30.0)) / math.sqrt(3.0 + s * s)
    sxx, sout, syy = h["sigma_xx_mid"], h["sigma_out_mid"], h["sigma_yy_mid"]
    mean = (sxx + sout + syy) / 3.0
    q = np.sqrt(0.5 * ((sxx - sout) ** 2 + (sout - syy) ** 2 + (syy - sxx) ** 2))
    f = q + alpha * mean - k  # p = -mean
    scale = np.maximum(np.abs(syy), k)
    print(f"largest f / |sigma| on the cone {np.max(f / scale):.3g}; sigma_yy down to "
          f"{syy.min():.4g} Pa; eps_p_eq at the end {h['eps_p_mid'][-1]:.3g}")
    assert np.all(f <= 64 * EPS * scale)
    assert h["eps_p_mid"][-1] > 0.0
    assert_ranks_agree(scene, str(tmp_path), h,
                       ("sigma_yy_mid", "sigma_out_mid", "u_y_bottom", "eps_p_mid"))
