"""Kinematics and the UFL forms of the explicit scheme, axisymmetric or plane strain.

Axisymmetric: coordinates (r, z) = (x[0], x[1]) in metres, the displacement (u_r, u_z),
every integral with the full ring measure 2 pi r. Plane strain
(:mod:`.geometry`): coordinates (x, y), the displacement (u_x, u_y), every integral
with the slab's thickness t (m) and the out-of-plane strain 0. Either way assembled
masses are in kg, forces in N and energies in J (in plane strain: of the slab t).
Every form takes the geometry explicitly (no default), so that no caller can use ring
weights by omission.

Forms are sums over parts: a part is a material and the cell measure of the
body made of it, so bodies of different materials share one mesh and one space.
"""
from __future__ import annotations

import math
from typing import Protocol, Sequence

import ufl
from dolfinx import fem, mesh as dmesh

from .geometry import Geometry

# Quadrature degree for the stiffness: the hoop term u_r/r is rational, so no
# rule is exact; degree 2 puts three points inside each cell (r > 0 there).
STIFFNESS_DEGREE = 2
# r * phi_i is quadratic on a P1 triangle: degree 2 integrates the mass exactly.
MASS_DEGREE = 2


class Material(Protocol):
    density: float
    linear: bool

    def stress(self, eps: ufl.core.expr.Expr) -> ufl.core.expr.Expr: ...

    def wave_speed(self) -> float: ...


Part = tuple[Material, ufl.Measure]


def radius(domain: dmesh.Mesh) -> ufl.core.expr.Expr:
    """The radial coordinate r (m)."""
    return ufl.SpatialCoordinate(domain)[0]


def cell_measure(domain: dmesh.Mesh, cell_tags: dmesh.MeshTags | None, tag: int | None,
                 degree: int) -> ufl.Measure:
    """dx over the cells tagged ``tag`` (all cells if None) with a fixed quadrature degree."""
    dx = ufl.Measure("dx", domain=domain, subdomain_data=cell_tags,
                     metadata={"quadrature_degree": degree})
    return dx if tag is None else dx(tag)


def strain(u: ufl.core.expr.Expr, r: ufl.core.expr.Expr | None) -> ufl.core.expr.Expr:
    """Small strain as a 3x3 tensor in (r, theta, z) order, with eps_tt = u_r / r; with
    ``r`` None the plane-strain tensor in (x, out, y) order, eps_out = 0."""
    g = ufl.grad(u)
    e_rz = 0.5 * (g[0, 1] + g[1, 0])
    return ufl.as_tensor([[g[0, 0], 0, e_rz],
                          [0, 0 if r is None else u[0] / r, 0],
                          [e_rz, 0, g[1, 1]]])


def elastic_stress(material, eps: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
    """Stress (Pa) of a linear material, or the elastic stress lambda tr(eps) I + 2 mu eps
    of a path-dependent one (``linear = False``: its initial stiffness, for the stable dt,
    and its stress outputs with eps the elastic strain)."""
    if material.linear:
        return material.stress(eps)
    return material.lmbda * ufl.tr(eps) * ufl.Identity(3) + 2.0 * material.mu * eps


def stiffness_form(V: fem.FunctionSpace, parts: Sequence[Part], geometry: Geometry):
    """Bilinear form of K (N/m): sum over parts of int sigma(eps(u)) : eps(w) 2 pi r dx
    (plane strain: t dx, eps_out = 0)."""
    u, w = ufl.TrialFunction(V), ufl.TestFunction(V)
    if geometry.plane:
        t = geometry.thickness
        return sum(ufl.inner(elastic_stress(mat, strain(u, None)), strain(w, None)) * t * dx
                   for mat, dx in parts)
    r = radius(V.mesh)
    return sum(ufl.inner(elastic_stress(mat, strain(u, r)), strain(w, r)) * 2 * math.pi * r * dx
               for mat, dx in parts)


def lumped_mass_form(V: fem.FunctionSpace, parts: Sequence[Part], geometry: Geometry):
    """Linear form of the lumped mass (kg): the row sums of the consistent mass,
    int 2 pi r rho phi_i . (1, 1) dx (plane strain: int t rho phi_i . (1, 1) dx). It is
    positive on the axis. The measures of ``parts`` must integrate r * phi exactly
    (degree >= 2)."""
    w = ufl.TestFunction(V)
    one = ufl.as_vector((1.0, 1.0))
    if geometry.plane:
        t = geometry.thickness
        return sum(mat.density * ufl.inner(one, w) * t * dx for mat, dx in parts)
    r = radius(V.mesh)
    return sum(mat.density * ufl.inner(one, w) * 2 * math.pi * r * dx for mat, dx in parts)


def traction_form(V: fem.FunctionSpace, facet_tags: dmesh.MeshTags, tag: int,
                  geometry: Geometry, traction: tuple[float, float] | None = None,
                  degree: int = MASS_DEGREE):
    """Linear form of the nodal force (N) of a unit surface load on facets ``tag``:
    int t . w 2 pi r ds (plane strain: int t . w t ds, t the thickness).

    With ``traction=None`` the load is a unit pressure (1 Pa) pushing into the body
    (t = -n); otherwise ``traction`` is the (t_r, t_z) traction ((t_x, t_y) in plane
    strain) in Pa per unit of the load's time function.
    """
    domain = V.mesh
    w = ufl.TestFunction(V)
    t = -ufl.FacetNormal(domain) if traction is None else ufl.as_vector(traction)
    ds = ufl.Measure("ds", domain=domain, subdomain_data=facet_tags,
                     metadata={"quadrature_degree": degree})
    if geometry.plane:
        return ufl.inner(t, w) * geometry.thickness * ds(tag)
    r = radius(domain)
    return ufl.inner(t, w) * 2 * math.pi * r * ds(tag)


def tensor_of(a: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
    """The 3x3 tensor in (r, theta, z) order of a four-component (rr, tt, zz, rz) vector."""
    return ufl.as_tensor([[a[0], 0, a[3]], [0, a[1], 0], [a[3], 0, a[2]]])


def stress_components(u: fem.Function, material: Material, geometry: Geometry,
                      eps_p: ufl.core.expr.Expr | None = None) -> dict[str, ufl.core.expr.Expr]:
    """Named stress components (Pa) for output, by their internal (slot) names: rr, zz,
    hoop (tt), rz and von Mises (plane strain: xx, yy, out, xy in those slots; the strain
    out of the plane 0, its stress the material's).

    A path-dependent material gives C : (eps(u) - eps_p), ``eps_p`` its plastic
    strain as a four-component (rr, tt, zz, rz) field (per cell for output)."""
    eps = strain(u, None if geometry.plane else radius(u.function_space.mesh))
    s = elastic_stress(material, eps if eps_p is None else eps - tensor_of(eps_p))
    dev = s - ufl.tr(s) / 3.0 * ufl.Identity(3)
    return {
        "sigma_rr": s[0, 0],
        "sigma_zz": s[2, 2],
        "sigma_tt": s[1, 1],
        "sigma_rz": s[0, 2],
        "von_mises": ufl.sqrt(1.5 * ufl.inner(dev, dev)),
    }
