"""A material added outside the library (demos/custom_material.py) runs with the solver as is.

Oracles: LinearElastic (the isotropic special case assembles the same K to
round-off), the compliance matrix inverted by numpy (the stress of a linear
displacement field, evaluated by dolfinx at a cell midpoint), the closed-form
dilatational speed, and the exact 1D wave of a rod with nu_zp = 0 (speed
sqrt(E_z / rho), within one element over the probe distance, as in test_wave).
Round-off bounds count roundings (tests/roundoff.py).
"""
import math

import numpy as np
import pytest
from mpi4py import MPI

from conftest import load_demo
from impact_fenics import forms, meshing
from impact_fenics.geometry import AXISYMMETRIC_GEOMETRY
from impact_fenics.materials import LinearElastic
from roundoff import LIBM, ledger, rounding

cm = load_demo("custom_material")
CONSTANTS = dict(E_p=10e9, nu_p=0.4, E_z=140e9, nu_zp=0.3, G_z=5e9, density=1600.0)


def _compliance_inverse(E_p, nu_p, E_z, nu_zp, G_z, density) -> np.ndarray:
    """The normal (r, theta, z) stiffness block as the inverse of the compliance."""
    S = np.array([[1 / E_p, -nu_p / E_p, -nu_zp / E_z],
                  [-nu_p / E_p, 1 / E_p, -nu_zp / E_z],
                  [-nu_zp / E_z, -nu_zp / E_z, 1 / E_z]])
    return np.linalg.inv(S)


def test_isotropic_case_is_linear_elastic():
    """The two D matrices (Lame's constants, the inverted compliance: about 12 roundings
    each), then the same quadrature of B' D B on both (its sums rounded alike or in
    another order, 20 more): 64 roundings of |K| (the Frobenius norm's ratio)."""
    assert cm.isotropic_check(comm=MPI.COMM_WORLD) <= rounding(64)
    m = cm.isotropic(200e9, 0.3, 7850.0)
    # sqrt(M / rho) with M from E and nu by two formulas: 8 roundings and a sqrt each
    assert math.isclose(m.wave_speed(), LinearElastic(200e9, 0.3, 7850.0).wave_speed(),
                        rel_tol=rounding(2 * (8 + LIBM)))


def test_stiffness_is_the_inverse_compliance():
    c = cm.TransverselyIsotropic(**CONSTANTS).stiffness()
    C = _compliance_inverse(**CONSTANTS)
    # a 3 x 3 inverse (LAPACK, and the closed form): 9 roundings a row times the condition
    # number of the compliance, for each
    tol = rounding(2 * 9 * np.linalg.cond(np.linalg.inv(C)))
    for key, value in (("C11", C[0, 0]), ("C12", C[0, 1]), ("C13", C[0, 2]), ("C33", C[2, 2])):
        assert math.isclose(c[key], value, rel_tol=tol), key
    assert c["C44"] == CONSTANTS["G_z"]


def test_stress_of_a_linear_field(comm):
    """u = (a r + c z, b z): eps_rr = a, eps_tt = a + c z / r, eps_zz = b, eps_rz = c / 2."""
    from dolfinx import fem
    from dolfinx.mesh import compute_midpoints

    from impact_fenics.compat import eval_expression, vector_space

    a, b, c = 1e-3, -2e-3, 4e-4
    material = cm.TransverselyIsotropic(**CONSTANTS)
    tmesh = meshing.bar(radius=0.05, length=0.1, h=0.025, comm=comm)
    V = vector_space(tmesh.mesh, "Lagrange", 1)
    u = fem.Function(V)
    u.interpolate(lambda x: np.vstack([a * x[0] + c * x[1], b * x[1]]))
    components = forms.stress_components(u, material, AXISYMMETRIC_GEOMETRY)
    n_cells = tmesh.mesh.topology.index_map(2).size_local
    cells = np.arange(n_cells, dtype=np.int32)
    mid = compute_midpoints(tmesh.mesh, 2, cells)
    C = _compliance_inverse(**CONSTANTS)
    eps = np.stack([np.full(n_cells, a), a + c * mid[:, 1] / mid[:, 0], np.full(n_cells, b)])
    expected = {"sigma_rr": C[0] @ eps, "sigma_tt": C[1] @ eps, "sigma_zz": C[2] @ eps,
                "sigma_rz": np.full(n_cells, CONSTANTS["G_z"] * c)}
    centroid = np.array([[1.0 / 3.0, 1.0 / 3.0]])
    # the strain from the nodal values: 16 roundings of 3 |u|_max / h (the gradient's
    # terms cancel), u_r / r at the centroid likewise of |u_r| / r; then C (6 roundings)
    u_max = abs(a) * 0.05 + abs(c) * 0.1 + abs(b) * 0.1
    strain_round = rounding(16, max(3 * u_max / 0.025, np.abs(eps).max()))
    atol = np.abs(C).max() * 3 * strain_round + rounding(6, np.abs(C).max() * np.abs(eps).max())
    for name, want in expected.items():
        got = eval_expression(fem.Expression(components[name], centroid), tmesh.mesh, cells)[:, 0]
        assert np.allclose(got, want, rtol=0, atol=atol), name


def test_wave_speed_along_the_axis():
    rod = cm.TransverselyIsotropic(**dict(CONSTANTS, nu_zp=0.0))
    # no coupling: C33 = E_z through the closed-form inverse (a few roundings, 8)
    assert math.isclose(rod.stiffness()["C33"], rod.E_z, rel_tol=rounding(8))
    # sqrt(C33 / rho) against sqrt(E_z / rho): C33's roundings, and a sqrt each
    assert rod.wave_speed() >= rod.bar_wave_speed() * (1 - rounding(8 + 2 * LIBM))


def test_invalid_constants_are_refused():
    from impact_fenics.errors import InputError

    with pytest.raises(InputError, match="positive definite"):
        cm.TransverselyIsotropic(**dict(CONSTANTS, nu_zp=3.0))


def test_pulse_in_the_rod_travels_at_sqrt_E_z_over_rho():
    s, _ = cm.run(None, h=0.01)
    assert s["status"] == "completed"
    assert s["wave_speed_error_rel"] <= s["h"] / s["probe_distance"]
    assert s["energy_balance_error_rel"] <= ledger(s["n_steps"], s["n_dofs"])


class _Without:
    """The demo's material with one attribute taken away (what a user's class may lack)."""

    def __init__(self, material, missing: str):
        self._material, self._missing = material, missing

    def __getattr__(self, name):
        if name == self._missing or name.startswith("_"):
            raise AttributeError(name)
        return getattr(self._material, name)


@pytest.mark.parametrize("missing", ["density", "linear", "stress", "wave_speed"])
def test_a_material_without_an_attribute_is_refused_in_one_line(missing):
    """A material lacking what the solver reads of it (the protocol of the demo's
    docstring) is refused when the model is made, in one line naming the class and the
    attribute (InputError: exit 2 from a main decorated with user_errors)."""
    from impact_fenics.bodies import Body, DeformableModel
    from impact_fenics.errors import InputError

    tmesh = meshing.bar(radius=0.05, length=0.1, h=0.05)
    material = _Without(cm.TransverselyIsotropic(**CONSTANTS), missing)
    with pytest.raises(InputError) as err:
        DeformableModel(tmesh, [Body("bar", material)])
    message = str(err.value)
    assert "\n" not in message
    assert message.startswith(f"body 'bar': the material _Without has no attribute '{missing}'")


@pytest.mark.parametrize("missing", ["update", "params", "n_state"])
def test_a_path_dependent_material_without_its_update_is_refused(missing):
    """linear = False: the point update, its parameters and state size are read too."""
    from impact_fenics.bodies import Body, DeformableModel
    from impact_fenics.errors import InputError
    from impact_fenics.materials import J2

    tmesh = meshing.bar(radius=0.05, length=0.1, h=0.05)
    material = _Without(J2(yield_stress=300e6), missing)
    with pytest.raises(InputError, match=f"the material _Without has no attribute '{missing}' "
                                         r"\(a path-dependent material needs"):
        DeformableModel(tmesh, [Body("bar", material)])
