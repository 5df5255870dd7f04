"""Node-to-node constraints from facet groups, in one global order on every rank.

A constraint i ties a lower dof (the z dof of a node of the body below) to an
upper side (the z dof of a node of the body above, or a rigid body):

    g_i = b_i + u_upper,i - u_lower,i >= 0      (m; g < 0 is penetration)

Constraints are sorted by radius, so the order is the same for every partition.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..bodies import Z, DeformableModel
from ..errors import InputError


@dataclass
class Constraints:
    """Replicated description of n node-to-node constraints (global order)."""

    r: np.ndarray          # radius of each constraint (m)
    b: np.ndarray          # initial gap (m), >= 0
    lower: np.ndarray | None  # global z dof of the lower node, None for a rigid lower side
    upper: np.ndarray | None  # global z dof of the upper node, None for a rigid upper side
    names: tuple[str, str]  # (lower group, upper group or rigid body name)

    @property
    def n(self) -> int:
        return int(self.r.size)


def _surface_nodes(model: DeformableModel, facet_name: str) -> tuple[np.ndarray, np.ndarray]:
    """All (r, z) and global z dofs of the nodes of a facet group, gathered on every rank."""
    dofs = model.facet_dofs(facet_name, Z)
    xy = model.dof_coordinates(dofs)
    glob = model.to_global(dofs)
    all_xy = np.concatenate(model.comm.allgather(xy)) if model.comm.size > 1 else xy
    all_dofs = np.concatenate(model.comm.allgather(glob)) if model.comm.size > 1 else glob
    order = np.lexsort((all_xy[:, 1], all_xy[:, 0]))
    return all_xy[order], all_dofs[order]


def _describe(xy: np.ndarray, axes: tuple[str, str], limit: int = 5) -> str:
    """The first ``limit`` points, named by the geometry's ``axes`` ((r, z) or (x, y))."""
    a, b = axes
    pts = ", ".join(f"({a}={p[0]:.6g}, {b}={p[1]:.6g})" for p in xy[:limit])
    more = f" and {len(xy) - limit} more" if len(xy) > limit else ""
    return pts + more


def pair_surfaces(model: DeformableModel, lower: str, upper: str,
                  tol: float | None = None) -> Constraints:
    """Pair the nodes of facet groups ``lower`` and ``upper`` by radius within ``tol`` (m).

    Every node of each surface must have exactly one partner at the same radius;
    otherwise an InputError names the unmatched nodes. ``tol`` defaults to 1e-6
    of the model size.
    """
    lo_xy, lo_dofs = _surface_nodes(model, lower)
    up_xy, up_dofs = _surface_nodes(model, upper)
    tol = 1e-6 * model.length_scale if tol is None else tol
    # nearest partner in r for each node of each side (both sorted by r)
    j = np.clip(np.searchsorted(up_xy[:, 0], lo_xy[:, 0]), 1, max(1, len(up_xy) - 1))
    if len(up_xy) == 0 or len(lo_xy) == 0:
        raise InputError(f"contact surfaces '{lower}' and '{upper}' do not pair: "
                         f"{len(lo_xy)} and {len(up_xy)} nodes")
    cand = np.stack([j - 1, np.minimum(j, len(up_xy) - 1)])
    dist = np.abs(up_xy[cand, 0] - lo_xy[None, :, 0])
    partner = cand[np.argmin(dist, axis=0), np.arange(len(lo_xy))]
    ok = np.abs(up_xy[partner, 0] - lo_xy[:, 0]) <= tol
    unmatched_lo = lo_xy[~ok]
    used = np.zeros(len(up_xy), dtype=bool)
    used[partner[ok]] = True
    twice = np.bincount(partner[ok], minlength=len(up_xy)) > 1
    unmatched_up = up_xy[~used | twice]
    if len(unmatched_lo) or len(unmatched_up):
        parts = []
        if len(unmatched_lo):
            parts.append(f"'{lower}' nodes without a partner: "
                         f"{_describe(unmatched_lo, model.geometry.axes)}")
        if len(unmatched_up):
            parts.append(f"'{upper}' nodes without a single partner: "
                         f"{_describe(unmatched_up, model.geometry.axes)}")
        raise InputError(f"contact surfaces '{lower}' and '{upper}' do not pair node to node "
                         f"within {tol:.3g} m; " + "; ".join(parts))
    b = up_xy[partner, 1] - lo_xy[:, 1]
    if np.any(b < -tol):
        bad = lo_xy[b < -tol]
        raise InputError(f"contact surfaces '{lower}' and '{upper}' overlap initially "
                         f"(negative gap) at {_describe(bad, model.geometry.axes)}")
    return Constraints(r=lo_xy[:, 0].copy(), b=np.maximum(b, 0.0), lower=lo_dofs.copy(),
                       upper=up_dofs[partner].copy(), names=(lower, upper))


def rigid_face(model: DeformableModel, surface: str, radius: float, body_name: str = "punch",
               profile: Callable[[np.ndarray], np.ndarray] | None = None) -> Constraints:
    """Constraints between a rigid body above and the nodes of ``surface`` with |r| <= radius
    (m): in axisymmetry the face's radius (r >= 0), in plane strain its half-width b about
    x = 0 (|x| <= b; a half model's face is x in [0, b]).

    ``profile(r)`` gives the initial gap b(r) >= 0 (m) under each node; a flat
    face touching the surface (b = 0) by default.
    """
    if not radius > 0:
        raise InputError(f"rigid face radius = {radius} m: must be > 0")
    xy, dofs = _surface_nodes(model, surface)
    keep = _on_face(model, xy, radius)
    if not np.any(keep):
        raise InputError(f"no node of '{surface}' lies within |r| <= {radius} m")
    r = xy[keep, 0]
    b = np.zeros_like(r) if profile is None else np.asarray(profile(r), dtype=float)
    if b.shape != r.shape or np.any(b < 0) or not np.all(np.isfinite(b)):
        raise InputError("rigid face profile must give a finite gap b(r) >= 0 (m) at every node")
    return Constraints(r=r.copy(), b=b.copy(), lower=dofs[keep].copy(), upper=None,
                       names=(surface, body_name))


def _on_face(model: DeformableModel, xy: np.ndarray, radius: float) -> np.ndarray:
    """Which nodes (r, z) (m) lie on a rigid face of radius (half-width) ``radius`` (m):
    |r| <= radius, within 1e-9 of the model's length scale."""
    return np.abs(xy[:, 0]) <= radius + 1e-9 * max(model.length_scale, radius)


def face_nodes(model: DeformableModel, surface: str, radius: float,
               component: int) -> np.ndarray:
    """The owned dofs of ``component`` of the nodes :func:`rigid_face` selects on
    ``surface`` (|r| <= ``radius``, m)."""
    if not radius > 0:
        raise InputError(f"rigid face radius = {radius} m: must be > 0")
    dofs = model.facet_dofs(surface, component)
    return dofs[_on_face(model, model.dof_coordinates(dofs), radius)]


def spherical_button(sphere_radius: float) -> Callable[[np.ndarray], np.ndarray]:
    """Initial gaps b(r) = R_s - sqrt(R_s^2 - r^2) (m) under a spherical button of radius
    R_s (m) touching the surface at r = 0 (in plane strain a cylinder along the slab's
    thickness, touching at x = 0, the same formula in x): a ``profile`` for
    :func:`rigid_face`, whose face radius (half-width) must not exceed R_s."""
    if not sphere_radius > 0:
        raise InputError(f"button radius = {sphere_radius} m: must be > 0")

    def profile(r: np.ndarray) -> np.ndarray:
        if np.any(np.abs(r) > sphere_radius):
            raise InputError(f"rigid face reaches |r| = {float(np.max(np.abs(r))):.6g} m beyond the "
                             f"button radius {sphere_radius} m")
        return sphere_radius - np.sqrt(sphere_radius ** 2 - r * r)

    return profile
