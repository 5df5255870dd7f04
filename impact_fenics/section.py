"""A section: the axial force (N) through a plane z = const of nodes of one linear body.

The plane is a row of the body's nodes: no cell of the body has nodes on both sides of
it. It splits the body's cells into those below (every node at z <= z_s) and those
above. The stiffness splits with them, K = K_below + K_above (N/m), and the step of the
linear bodies (v^{n+1/2} = v^{n-1/2} + h M^-1 (f_ext - K u^n), M lumped) moves each
node by the forces of the cells it belongs to. The section's force at step n is the z
force that the cells below exert on the plane's nodes P,

    F_s^n = - sum_{i in P} (K_below u^n)_{i,z}       (N; compression positive),

positive when the body is compressed across the plane (the cells below push the plane
up). It is exact in this sense: let the part beyond be the body's nodes at z >= z_s (the
plane's nodes included). A uniform z displacement strains no cell, so the z rows of
K_above sum to zero over the nodes of the cells above: sum_i (K_above u)_{i,z} = 0 for
every u. The cells below touch the part beyond only at P. So the part's z momentum
p = sum_{z_i >= z_s} m_i v_{i,z} changes over a step by

    p^{n+1/2} - p^{n-1/2} = h (F_s^n + F_other^n),

F_other^n the other forces on those nodes (loads, contact, the reactions of fixed z
dofs), and over a run sum_n h F_s^n + sum_n h F_other^n is the change of p, to round-off;
the nodes below the plane (P excluded) see - F_s^n the same way. Nodes that another
body's cells share are not allowed (one body at the plane).

Since sum_{i in P} (K_below u)_{i,z} = (K_below^T 1_P) . u, the section is one dot
product F_s = c . u with c = - K_below 1_P (K symmetric): the nodal forces of the cells
below when the plane alone moves up by 1 m. Only the cells below that touch the plane
contribute (the others do not see 1_P): c lives on their dofs, a few per plane node. c
is assembled once, over those cells, by the operator's own element: on triangles the
action of the stiffness form on 1_P, on quadrilaterals the B-bar element matrices
(:func:`.operators.bbar_element_matrices`' arithmetic). Its entries and dofs are known
on every rank, ordered by (z, r, component) of the node, so the dot product sums in
the same order on every partition.

A section needs a linear elastic body: the force of a path-dependent or finite-strain
body is not K u.
"""
from __future__ import annotations

import math

import numpy as np
import ufl
from mpi4py import MPI

from .compat import geometry_dofs
from .errors import InputError


def _body_cells(model, name: str) -> tuple[np.ndarray, np.ndarray]:
    """The local cells (owned and ghost) of body ``name`` and their nodes' (r, z) from
    the mesh geometry (cells, nodes, 2) in m: the coordinates as given, which the dof
    coordinates recompute with round-off."""
    cells = np.sort(model.tmesh.cells(name)).astype(np.int32)
    xy = model.mesh.geometry.x[geometry_dofs(model.mesh)[cells], :2]
    return cells, xy


def _tolerance(model) -> float:
    """Nodes within this distance (m) of the plane are on it (as the axis' nodes)."""
    return 1e-10 * max(model.length_scale, 1e-300)


def section_body(model, z: float) -> str:
    """The one body the plane z (m) passes through (cells of it on both sides), checked:
    linear elastic, and the plane a row of its nodes. Refused (InputError) otherwise, in
    a line naming the problem (collective)."""
    from .materials import is_finite

    tol = _tolerance(model)
    through = []
    for name in model.bodies:
        _, xy = _body_cells(model, name)
        lo = float(xy[..., 1].min()) if xy.size else math.inf
        hi = float(xy[..., 1].max()) if xy.size else -math.inf
        lo, hi = model.comm.allreduce(lo, op=MPI.MIN), model.comm.allreduce(hi, op=MPI.MAX)
        if lo < z - tol and hi > z + tol:
            through.append(name)
    if not through:
        raise InputError(f"the plane z = {z!r} m passes through no body (a section needs "
                         "cells of one body on both sides)")
    if len(through) > 1:
        raise InputError(f"the plane z = {z!r} m passes through the bodies "
                         f"{' and '.join(through)}: a section goes through one")
    name = through[0]
    material = model.bodies[name].material
    if not material.linear or is_finite(material):
        raise InputError(f"body '{name}' is not linear elastic: a section's force K u needs "
                         "a linear body (not a path-dependent or finite-strain one)")
    _, xy = _body_cells(model, name)
    z_nodes = xy[..., 1]
    cut = np.any(z_nodes < z - tol, axis=1) & np.any(z_nodes > z + tol, axis=1)
    if model.comm.allreduce(int(cut.sum())):
        raise InputError(f"the plane z = {z!r} m cuts cells of body '{name}': a section is a "
                         "row of its nodes (put it at the height of one)")
    cells, _ = _body_cells(model, name)
    plane = np.unique(model.cell_dofs[cells][np.abs(z_nodes - z) <= tol])
    shared = [other for other in model.bodies if other != name
              and np.isin(plane, model.cell_dofs[model.tmesh.cells(other)]).any()]
    shared = sorted(set().union(*model.comm.allgather(set(shared))))
    if shared:
        raise InputError(f"the plane z = {z!r} m of body '{name}' has nodes of body "
                         f"{' and '.join(shared)} too: a section's nodes belong to one body")
    return name


def section_row(model, name: str, z: float) -> tuple[np.ndarray, np.ndarray]:
    """The section of body ``name`` at the plane z (m) as F_s = c . u: the scene global
    indices of its dofs and c (N/m), on every rank, ordered by the node's (z, r) then the
    component (see the module; :func:`section_body` checks the plane first). Collective."""
    tol = _tolerance(model)
    cells, xy = _body_cells(model, name)
    z_nodes = xy[..., 1]
    on = np.abs(z_nodes - z) <= tol  # (cells, nodes): the plane's nodes
    layer = np.all(z_nodes <= z + tol, axis=1) & np.any(on, axis=1)  # below, touching it
    n_nodes = model.n_local // model.bs
    plane = np.zeros(n_nodes, dtype=np.bool_)
    plane[model.cell_dofs[cells][on]] = True
    if model.quadrilateral:
        force = _quad_action(model, name, cells[layer], plane)
    else:
        force = _triangle_action(model, name, cells[layer], plane)
    # the dofs of the layer's nodes this rank owns, with the node's coordinates; a node
    # of the layer may be owned by a rank that holds none of the layer's cells (a
    # partition along the plane: it holds the node's cells above only), so each rank
    # marks the layer's nodes it sees and the marks are summed onto their owners
    from dolfinx import fem

    from .compat import scatter_add

    mark = fem.Function(model.V)
    mark.x.array[model.bs * np.unique(model.cell_dofs[cells[layer]].ravel())] = 1.0
    scatter_add(mark.x)
    nodes = np.flatnonzero(mark.x.array[: model.n_owned: model.bs] > 0)
    coords = np.zeros((n_nodes, 2))
    coords[model.cell_dofs[cells].ravel()] = xy.reshape(-1, 2)
    scene = model.dofs.local_to_scene()
    unrolled = (2 * nodes[:, None] + np.arange(2)).ravel()
    mine = np.column_stack([np.repeat(coords[nodes, 1], 2), np.repeat(coords[nodes, 0], 2),
                            np.tile(np.arange(2.0), nodes.size), scene[unrolled].astype(float),
                            -force[unrolled]])
    rows = np.concatenate(model.comm.allgather(mine)) if model.comm.size > 1 else mine
    rows = rows[np.lexsort((rows[:, 2], rows[:, 1], rows[:, 0]))]
    return rows[:, 3].astype(np.int64), np.ascontiguousarray(rows[:, 4])


def _triangle_action(model, name: str, layer: np.ndarray, plane: np.ndarray) -> np.ndarray:
    """K_layer 1_P (N/m) on the owned unrolled dofs: the action of body ``name``'s
    stiffness form over the layer's cells on the plane's unit z displacement."""
    from dolfinx import fem
    from dolfinx.mesh import meshtags

    from .forms import cell_measure, stiffness_form
    from .operators import assemble_owned

    mesh = model.mesh
    tags = meshtags(mesh, mesh.topology.dim, layer, np.ones(layer.size, dtype=np.int32))
    material, dx = model.parts[model.part_names.index(name)]
    degree = dx.metadata()["quadrature_degree"]
    one = fem.Function(model.V)
    one.x.array[1::2] = plane.astype(float)
    form = stiffness_form(model.V, [(material, cell_measure(mesh, tags, 1, degree))],
                          model.geometry)
    return assemble_owned(model, ufl.action(form, one))


def _quad_action(model, name: str, layer: np.ndarray, plane: np.ndarray) -> np.ndarray:
    """K_layer 1_P (N/m) on the owned unrolled dofs from the B-bar element matrices of
    the layer's owned cells of body ``name`` (ghost contributions summed)."""
    from dolfinx import fem

    from . import q1
    from .compat import scatter_add
    from .operators import elastic_stiffness

    material = model.bodies[name].material

    n_owned_cells = model.mesh.topology.index_map(2).size_local
    owned = layer[layer < n_owned_cells]
    g = q1.QuadGeometry(model.cell_dofs, model.node_xy, owned, model.geometry)
    Ke = np.empty((owned.size, 8, 8))
    q1.bbar_element_matrices(g.dNdR, g.dNdZ, g.N, g.inv_R, g.w, elastic_stiffness(material), Ke)
    dofs = (2 * g.dofs[:, :, None] + np.arange(2)).reshape(-1, 8)  # (n, 8) unrolled
    one = np.zeros((owned.size, 8))
    one[:, 1::2] = plane[g.dofs]
    out = fem.Function(model.V)
    np.add.at(out.x.array, dofs.ravel(), np.einsum("nij,nj->ni", Ke, one).ravel())
    scatter_add(out.x)
    return out.x.array[: model.n_owned].copy()
