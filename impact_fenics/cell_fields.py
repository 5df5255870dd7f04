"""Cell values of the P1 displacement: strain and stress at the DG0 point (the centroid).

On a linear (P1) triangle the gradient of u is constant, and at the centroid
u_r = (u_r1 + u_r2 + u_r3) / 3 and r = (r1 + r2 + r3) / 3, so the axisymmetric
strain of a cell in the point notation of :mod:`.materials.axisym`,

    eps = (du_r/dr, u_r/r, du_z/dz, (du_r/dz + du_z/dr) / 2)    (rr, tt, zz, rz),

is a few flops from the cell's three nodes: the value a UFL Expression of
``forms.strain`` gives at the DG0 interpolation point, to round-off. A linear
material maps it to the stress by a constant 4x4 matrix D (Pa), read once
from the material's UFL ``stress`` applied to the four unit strains; a material
whose stress cannot be read that way (one that depends on position, say) is
evaluated with a compiled UFL Expression per body instead (slower, the same values).

Output components (Pa): sigma_rr, sigma_zz, sigma_tt, sigma_rz and von Mises,
sqrt(3/2 dev(sigma) : dev(sigma)).

**Plane strain** (:mod:`.geometry`) keeps the slots (xx, out, yy, xy) and their kernels:
the out-of-plane strain is 0, so the factor g4 of :func:`gradient_factors` is 0 (the
product (u_1 + u_2 + u_3) g4 is an exact 0) and a Q1 cell's geometry has inv_R = 0; the
cell's stress is then D eps with eps_out = 0 (sigma_out = lambda (eps_xx + eps_yy) for
isotropic elasticity), and the rule's weights are t |J| W_q, equal on a triangle, so the
centroid's value is again their weighted mean.

**What a cell's stress is.** For every body it is the mean of the stresses at the
points of the stiffness rule, weighted as the rule weights them (w_q |J| 2 pi r_q):
sum_q w_q sigma_q / sum_q w_q. A path-dependent body outputs exactly that, from the
stresses its material's point update computes at the displacement written
(:meth:`~.internal_force.quadrature.QuadratureForce.point_stresses`,
:func:`point_mean_stress`); each point stress satisfies the yield condition, and so
does their mean (the yield surfaces here are convex). A linear body outputs D eps at
the centroid, which is that mean in exact arithmetic: eps_rr, eps_zz and eps_rz are
constant on a P1 triangle, and with the three equal rule weights times r_q the mean
hoop strain is sum_q u_r(x_q) / sum_q r_q = u_r / r at the centroid (the points'
mean is the centroid); D is linear.

Per output (:class:`CellStress`), with each cell's inverse Jacobian computed once at
set-up: one pass gathers the nodal displacements and writes the four components
(straight into a field writer's frame, when given its rows), a second computes von
Mises over the body's contiguous cells, a loop the compiler vectorizes, and a third the
extremes. Bodies of one D are one pass (a call costs a few us: most of a small mesh's
frame), and an isotropic D takes lambda tr(eps) + 2 mu eps (9 flops, not the 28 of
D eps: the same values to a few 1e-16 of the largest). On the punch's 21,792 cells
0.16 ms against 0.22 ms with a general D and numpy's extremes; the bars' 1,008: 10 us
against 20 us (loaded machine). The three passes of one isotropic range of cells are
one call (:func:`isotropic_stress_range`), through its compiled entry in an output
loop, with the nodes' u_r dofs unsigned (no check for a negative index): the bars'
frame 7.8 us in the loop against 13.3 (median of 20 outputs, loaded machine).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .compat import eval_expression
from .jit_watch import contiguous_float64, direct
from .materials import is_finite

STRESS_NAMES = ("sigma_rr", "sigma_zz", "sigma_tt", "sigma_rz", "von_mises")
# the output components in the point notation (rr, tt, zz, rz)
_COMPONENT = {"sigma_rr": 0, "sigma_tt": 1, "sigma_zz": 2, "sigma_rz": 3}
_TENSOR = ((0, 0), (1, 1), (2, 2), (0, 2))  # (r, theta, z) tensor entries of the notation


def stiffness_matrix(material) -> np.ndarray | None:
    """D (Pa, 4x4) with sigma = D eps in the notation (rr, tt, zz, rz), tensor shear; None
    if the material is not linear or its stress is not a constant map of the strain."""
    import ufl

    if not getattr(material, "linear", False):
        return None
    D = np.empty((4, 4))
    try:
        for j, (a, b) in enumerate(_TENSOR):
            unit = [[0.0] * 3 for _ in range(3)]
            unit[a][b] = unit[b][a] = 1.0
            s = material.stress(ufl.as_tensor(unit))
            for i, (p, q) in enumerate(_TENSOR):
                D[i, j] = float(s[p, q])
    except Exception:  # the stress needs a mesh (position, a Function): not a constant map
        return None
    return D


def isotropic_stiffness(lmbda: float, mu: float) -> np.ndarray:
    """D (Pa, 4x4) of isotropic elasticity in the notation (rr, tt, zz, rz), tensor shear:
    sigma = lambda tr(eps) I + 2 mu eps."""
    D = np.full((4, 4), 0.0)
    D[:3, :3] = lmbda
    D[[0, 1, 2], [0, 1, 2]] = lmbda + 2.0 * mu
    D[3, 3] = 2.0 * mu
    return D


@njit(cache=True)
def triangle_strain(r1, z1, r2, z2, r3, z3, ur1, uz1, ur2, uz2, ur3, uz3, plane=False):
    """Strain (rr, tt, zz, rz; tensor shear) at the centroid of a P1 triangle with nodes
    (r_k, z_k) in m and displacements (ur_k, uz_k) in m; ``plane``: plane strain, the
    second component (out of the plane) 0."""
    r21, z21, r31, z31 = r2 - r1, z2 - z1, r3 - r1, z3 - z1
    det = r21 * z31 - r31 * z21
    dur2, duz2, dur3, duz3 = ur2 - ur1, uz2 - uz1, ur3 - ur1, uz3 - uz1
    # grad u = [du/dxi] J^-1 with J = [[r21, r31], [z21, z31]]
    dur_dr = (dur2 * z31 - dur3 * z21) / det
    dur_dz = (dur3 * r21 - dur2 * r31) / det
    duz_dr = (duz2 * z31 - duz3 * z21) / det
    duz_dz = (duz3 * r21 - duz2 * r31) / det
    hoop = 0.0 if plane else ((ur1 + ur2 + ur3) / 3.0) / ((r1 + r2 + r3) / 3.0)
    return dur_dr, hoop, duz_dz, 0.5 * (dur_dz + duz_dr)


@njit(cache=True)
def stress_components(D, e0, e1, e2, e3):
    """(sigma_rr, sigma_tt, sigma_zz, sigma_rz) in Pa of sigma = D eps, for the strain
    (e0, e1, e2, e3) = (rr, tt, zz, rz) with tensor shear."""
    return (D[0, 0] * e0 + D[0, 1] * e1 + D[0, 2] * e2 + D[0, 3] * e3,
            D[1, 0] * e0 + D[1, 1] * e1 + D[1, 2] * e2 + D[1, 3] * e3,
            D[2, 0] * e0 + D[2, 1] * e1 + D[2, 2] * e2 + D[2, 3] * e3,
            D[3, 0] * e0 + D[3, 1] * e1 + D[3, 2] * e2 + D[3, 3] * e3)


@njit(cache=True)
def von_mises(s_rr, s_tt, s_zz, s_rz):
    """sqrt(3/2 dev(sigma) : dev(sigma)) (Pa) of the axisymmetric stress (shear s_rz)."""
    m = (s_rr + s_tt + s_zz) * (1.0 / 3.0)
    d0, d1, d2 = s_rr - m, s_tt - m, s_zz - m
    return math.sqrt(1.5 * (d0 * d0 + d1 * d1 + d2 * d2 + 2.0 * s_rz * s_rz))


@njit(cache=True)
def stress_outputs(D, e0, e1, e2, e3):
    """(sigma_rr, sigma_zz, sigma_tt, sigma_rz, von Mises) in Pa of sigma = D eps, for the
    strain (e0, e1, e2, e3) = (rr, tt, zz, rz) with tensor shear."""
    s_rr, s_tt, s_zz, s_rz = stress_components(D, e0, e1, e2, e3)
    return s_rr, s_zz, s_tt, s_rz, von_mises(s_rr, s_tt, s_zz, s_rz)


@njit(cache=True)
def gradient_factors(nodes, xy, g, plane=False) -> None:
    """Per P1 triangle with node (block) indices ``nodes`` (n, 3) and nodes at ``xy`` (r, z
    in m): g (n, 5) such that, with d_k = u_k - u_1 the nodal differences,
    du/dr = d_2 g0 + d_3 g1, du/dz = d_2 g2 + d_3 g3 (the inverse Jacobian of
    :func:`triangle_strain`, 1/m) and u_r / r at the centroid = (u_r1 + u_r2 + u_r3) g4;
    ``plane``: plane strain, g4 = 0 (eps_out = 0; x may be 0 or negative)."""
    for k in range(nodes.shape[0]):
        a, b, d = nodes[k, 0], nodes[k, 1], nodes[k, 2]
        r21, z21 = xy[b, 0] - xy[a, 0], xy[b, 1] - xy[a, 1]
        r31, z31 = xy[d, 0] - xy[a, 0], xy[d, 1] - xy[a, 1]
        det = r21 * z31 - r31 * z21
        g[k, 0] = z31 / det
        g[k, 1] = -z21 / det
        g[k, 2] = -r31 / det
        g[k, 3] = r21 / det
        g[k, 4] = 0.0 if plane else 1.0 / (xy[a, 0] + xy[b, 0] + xy[d, 0])


@njit(cache=True)
def cell_stress(dofs, g, u, D, eps_p, cells, out) -> None:
    """sigma_rr, sigma_zz, sigma_tt, sigma_rz (Pa) of sigma = D (eps - eps_p) at the centroid
    of each of ``cells`` into out[0:4, cells[k]] (von Mises follows in a pass of its own,
    :func:`von_mises_rows`, which the compiler vectorizes: this loop's gathers keep it
    scalar).

    ``dofs`` (n, 3) the u_r dofs of the cells' nodes (2 x the node's block index; an
    unsigned type spares each read of u a check for a negative index), ``g`` (n, 5)
    their :func:`gradient_factors`, ``u`` the unrolled displacement (m); ``eps_p`` (n, 4) a
    strain (rr, tt, zz, rz) to subtract per cell, or an empty
    (0, 4) array. The strain is :func:`triangle_strain`'s, with the inverse Jacobian
    computed once."""
    plastic = eps_p.shape[0] > 0
    for k in range(cells.size):
        a, b, d = dofs[k, 0], dofs[k, 1], dofs[k, 2]
        ur1, uz1 = u[a], u[a + 1]
        ur2, uz2, ur3, uz3 = u[b], u[b + 1], u[d], u[d + 1]
        dur2, duz2, dur3, duz3 = ur2 - ur1, uz2 - uz1, ur3 - ur1, uz3 - uz1
        e0 = dur2 * g[k, 0] + dur3 * g[k, 1]
        e1 = (ur1 + ur2 + ur3) * g[k, 4]
        e2 = duz2 * g[k, 2] + duz3 * g[k, 3]
        e3 = 0.5 * (dur2 * g[k, 2] + dur3 * g[k, 3] + duz2 * g[k, 0] + duz3 * g[k, 1])
        if plastic:
            e0 -= eps_p[k, 0]
            e1 -= eps_p[k, 1]
            e2 -= eps_p[k, 2]
            e3 -= eps_p[k, 3]
        s_rr, s_tt, s_zz, s_rz = stress_components(D, e0, e1, e2, e3)
        c = cells[k]
        out[0, c] = s_rr
        out[1, c] = s_zz
        out[2, c] = s_tt
        out[3, c] = s_rz


@njit(cache=True)
def _isotropic_stress(dofs, g, u, lmbda, two_mu, half_two_mu, eps_p, plastic, k):
    """(sigma_rr, sigma_zz, sigma_tt, sigma_rz) (Pa) of the k-th cell of
    :func:`isotropic_cell_stress` (inlined in its loops)."""
    a, b, d = dofs[k, 0], dofs[k, 1], dofs[k, 2]
    ur1, uz1 = u[a], u[a + 1]
    ur2, uz2, ur3, uz3 = u[b], u[b + 1], u[d], u[d + 1]
    dur2, duz2, dur3, duz3 = ur2 - ur1, uz2 - uz1, ur3 - ur1, uz3 - uz1
    g0, g1, g2, g3 = g[k, 0], g[k, 1], g[k, 2], g[k, 3]
    e0 = dur2 * g0 + dur3 * g1
    e1 = (ur1 + ur2 + ur3) * g[k, 4]
    e2 = duz2 * g2 + duz3 * g3
    gamma = dur2 * g2 + dur3 * g3 + duz2 * g0 + duz3 * g1  # 2 eps_rz
    if plastic:
        e0 -= eps_p[k, 0]
        e1 -= eps_p[k, 1]
        e2 -= eps_p[k, 2]
        gamma -= 2.0 * eps_p[k, 3]
    p = lmbda * (e0 + e1 + e2)
    return p + two_mu * e0, p + two_mu * e2, p + two_mu * e1, half_two_mu * gamma


@njit(cache=True)
def isotropic_cell_stress(dofs, g, u, lmbda, two_mu, eps_p, cells, out) -> None:
    """:func:`cell_stress` of an isotropic D (sigma = lambda tr(eps) I + 2 mu eps, Pa; the
    Lame constants ``lmbda`` and ``two_mu`` = 2 mu): 9 flops of stress a cell instead of
    the 28 of a general D, the same values to round-off (a few 1e-16 of the largest)."""
    plastic = eps_p.shape[0] > 0
    half_two_mu = 0.5 * two_mu
    for k in range(cells.size):
        c = cells[k]
        out[0, c], out[1, c], out[2, c], out[3, c] = _isotropic_stress(
            dofs, g, u, lmbda, two_mu, half_two_mu, eps_p, plastic, k)


@njit(cache=True)
def isotropic_stress_range(dofs, g, u, lmbda, two_mu, eps_p, first, out, peaks) -> None:
    """The five outputs (Pa) of the cells first, first + 1, ... (one per row of ``dofs``)
    into out[:, first:first + n] in one call: :func:`isotropic_cell_stress`'s stresses,
    then von Mises over the range (a loop the compiler vectorizes: the rows are slices
    of their own), then, if ``peaks`` has 3 entries, :func:`stress_peaks` over every
    cell of ``out`` (give them only when this range is the last of ``out`` to fill;
    an empty ``peaks`` skips them). The same values as those kernels called one by one;
    one call where they are three (a call costs ~0.5 us, a third of the bars' frame)."""
    plastic = eps_p.shape[0] > 0
    half_two_mu = 0.5 * two_mu
    n = dofs.shape[0]
    end = first + n
    s_rr, s_zz, s_tt = out[0, first:end], out[1, first:end], out[2, first:end]
    s_rz = out[3, first:end]
    for k in range(n):
        s_rr[k], s_zz[k], s_tt[k], s_rz[k] = _isotropic_stress(
            dofs, g, u, lmbda, two_mu, half_two_mu, eps_p, plastic, k)
    von_mises_rows(s_rr, s_zz, s_tt, s_rz, out[4, first:end])
    if peaks.size == 3:
        stress_peaks(out[4], out[1], peaks)


@njit(cache=True)
def point_mean_stress(sigma, w, cells, out) -> None:
    """out[0:4, cells[k]] = (sigma_rr, sigma_zz, sigma_tt, sigma_rz) (Pa) of the k-th cell:
    the mean of its point stresses sigma[k, q] ((rr, tt, zz, rz), Pa) weighted by the
    points' w[k, q] (m^3: rule weight x |J| x 2 pi r_q), sum_q w_q sigma_q / sum_q w_q.
    (Von Mises follows in a pass of its own.)"""
    for k in range(cells.size):
        total = s_rr = s_tt = s_zz = s_rz = 0.0
        for q in range(sigma.shape[1]):
            wq = w[k, q]
            total += wq
            s_rr += wq * sigma[k, q, 0]
            s_tt += wq * sigma[k, q, 1]
            s_zz += wq * sigma[k, q, 2]
            s_rz += wq * sigma[k, q, 3]
        c = cells[k]
        out[0, c] = s_rr / total
        out[1, c] = s_zz / total
        out[2, c] = s_tt / total
        out[3, c] = s_rz / total


@njit(cache=True)
def stress_peaks(vm, zz, peaks) -> None:
    """peaks = (max von Mises, max sigma_zz, -min sigma_zz) (Pa) of the rows ``vm`` and
    ``zz``, in one pass (contiguous rows: 12 us on 21,792 cells, numpy's three 14 us)."""
    vm_max, zz_max, zz_min = -np.inf, -np.inf, np.inf
    for c in range(vm.size):
        v, z = vm[c], zz[c]
        vm_max = v if v > vm_max else vm_max
        zz_max = z if z > zz_max else zz_max
        zz_min = z if z < zz_min else zz_min
    peaks[0], peaks[1], peaks[2] = vm_max, zz_max, -zz_min


# track_peaks' state: largest von Mises (Pa) and its time (s), largest sigma_zz and its
# time, smallest sigma_zz and its time, 1 once a frame was seen
PEAK_NAMES = ("von_mises", "von_mises_time", "sigma_zz_max", "sigma_zz_max_time",
              "sigma_zz_min", "sigma_zz_min_time")


@njit(cache=True)
def track_peaks(peaks, t, state) -> None:
    """The run's stress peaks over its frames (``state``, PEAK_NAMES then a seen flag)
    with a frame's ``peaks`` (:func:`stress_peaks`' (max von Mises, max sigma_zz, -min
    sigma_zz), Pa) at time ``t`` (s): each kept with its time when exceeded."""
    if state[6] == 0.0:
        state[0], state[2], state[4] = -np.inf, -np.inf, np.inf
        state[1] = state[3] = state[5] = t
        state[6] = 1.0
    if peaks[0] > state[0]:
        state[0], state[1] = peaks[0], t
    if peaks[1] > state[2]:
        state[2], state[3] = peaks[1], t
    if -peaks[2] < state[4]:
        state[4], state[5] = -peaks[2], t


def isotropic_lame(D: np.ndarray) -> tuple[float, float] | None:
    """(lambda, 2 mu) in Pa if D (4x4, tensor shear) is isotropic elasticity, to round-off;
    else None."""
    lmbda, two_mu = D[0, 1], D[3, 3]
    scale = np.abs(D).max()
    iso = isotropic_stiffness(lmbda, 0.5 * two_mu)
    if scale > 0 and np.abs(D - iso).max() <= 1e-14 * scale:
        return float(lmbda), float(two_mu)
    return None


@njit(cache=True)
def von_mises_rows(s_rr, s_zz, s_tt, s_rz, out) -> None:
    """out[k] = von Mises (Pa) of the k-th stresses (contiguous rows: a SIMD loop)."""
    for k in range(out.size):
        out[k] = von_mises(s_rr[k], s_tt[k], s_zz[k], s_rz[k])


@njit(cache=True)
def von_mises_cells(values, cells) -> None:
    """values[4, c] = von Mises (Pa) of values[0:4, c] for each of ``cells``."""
    for k in range(cells.size):
        c = cells[k]
        values[4, c] = von_mises(values[0, c], values[2, c], values[1, c], values[3, c])


class CellStress:
    """The five stress outputs (Pa) of every owned cell, body by body.

    ``evaluate(u)`` takes the unrolled displacement of the local nodes (owned and
    ghosts, m) and returns a (5, n_owned_cells) array in STRESS_NAMES order (``out``: the
    array to fill instead of its own); :attr:`peaks` then holds (max von Mises, max
    sigma_zz, -min sigma_zz) (Pa) over this rank's owned cells.

    A path-dependent body's cells get the weighted mean of the stresses of its points
    at ``u`` (:func:`point_mean_stress`; its force's :attr:`frame` then holds that
    state, for the frame's other cell fields). A finite-strain body's cells get the
    mean Cauchy stress of its points' update at ``u`` (the force's
    :meth:`~.internal_force.finite.FiniteStrainForce.frame_values`), and
    :attr:`finite_eps_p` and :attr:`finite_temperature` that update's: every value of a
    frame belongs to the u it writes.

    The common mesh (bodies of one isotropic D over a range of cells, no path-dependent
    body, no UFL Expression) is one compiled call, :func:`isotropic_stress_range`;
    called again with the very arrays ``u`` and ``out`` of the first call (an output
    loop's), it goes through the kernel's compiled entry, without numba's search by
    argument types.

    On a quadrilateral mesh a linear body's cell stress is D times the cell's
    ring-weighted mean strain (:func:`.q1.mean_strain`), the weighted mean of the B-bar
    point stresses."""

    def __init__(self, model, plastic_forces=(), finite_forces=()):
        V = model.V
        mesh = model.mesh
        self.model = model
        self.geometry = model.geometry
        self.n_cells = mesh.topology.index_map(2).size_local
        dofs = model.cell_dofs
        self.xy = np.ascontiguousarray(model.node_xy)
        self.values = np.zeros((len(STRESS_NAMES), self.n_cells))
        self.peaks = np.full(3, -np.inf)
        self._no_plastic = np.empty((0, 4))  # the kernels' eps_p to subtract: none
        self._no_peaks = np.empty(0)  # a range kernel that leaves the peaks to the end
        # per group of bodies of a constant D: (owned cells, their u_r dofs, gradient
        # factors, D, its (lambda, 2 mu) if isotropic, (first, end) when the cells are the
        # range first..end-1)
        self._kernel = []
        self._ufl = []  # (owned cells, [compiled Expression per output])
        # path-dependent bodies: the mean of their point stresses (owned cells, the force,
        # (first, end) or None as above)
        self._points = [(f.cells.astype(np.int64), f, _range(f.cells)) for f in plastic_forces]
        plastic = {f.body for f in plastic_forces}
        # finite-strain bodies: each cell's mean Cauchy stress (force.cell_values), by body
        # (the integrator's order: the bodies'; their owned cells sorted, as the forces')
        finite = [name for name, b in model.bodies.items() if is_finite(b.material)]
        self._finite = [(model.owned_cells(name).astype(np.int64), force)
                        for name, force in zip(finite, finite_forces)]
        plastic |= set(finite)
        # their cells' mean eps_bar_p (-) and temperature (K, a material with one) of the last
        # evaluation; eps_bar_p zero on the other cells, the temperature NaN there (a body
        # without one has none: not 0 K, which would also stretch a picture's colour range)
        self.finite_eps_p = np.zeros(self.n_cells)
        self.finite_temperature = np.full(self.n_cells, np.nan)
        self._has_temperature = [getattr(f.material, "temperature_index", -1) >= 0
                                 for f in finite_forces]
        by_d = []  # (D, [cells of the bodies of that D])
        self._quads = []  # Q1 linear bodies: (owned cells, their geometry, D, the mean strains)
        for body in model.bodies.values():
            if body.name in plastic:
                continue
            if getattr(model, "quadrilateral", False):
                from .q1 import QuadGeometry

                cells = np.sort(model.tmesh.cells(body.name))
                cells = cells[cells < self.n_cells].astype(np.int64)
                self._quads.append((cells, QuadGeometry(dofs, self.xy, cells, self.geometry),
                                    stiffness_matrix(body.material), np.zeros((cells.size, 4))))
                continue
            cells = model.tmesh.cells(body.name)
            cells = np.sort(cells[cells < self.n_cells]).astype(np.int64)
            D = stiffness_matrix(body.material)
            if D is None:
                self._ufl.append((cells.astype(np.int32), self._expressions(body.material)))
                continue
            for D_other, parts in by_d:
                if np.array_equal(D, D_other):
                    parts.append(cells)
                    break
            else:
                by_d.append((D, [cells]))
        # bodies of one D (the bars' striker and target, both steel) are one kernel call:
        # the per-call cost (a few us a call) is most of a small mesh's frame
        for D, parts in by_d:
            cells = np.sort(np.concatenate(parts))
            self._kernel.append((cells, *self._geometry(dofs[cells]), D, isotropic_lame(D),
                                 _range(cells)))
        self._u_fn = None
        # the whole evaluation in one call of isotropic_stress_range (peaks included)?
        one = (self._kernel[0] if len(self._kernel) == 1 and not self._ufl and not self._points
               and not self._finite else None)
        self._single = one is not None and one[4] is not None and one[5] is not None
        self._bound = None  # (u, out, compiled entry, its arguments) once bound

    def _geometry(self, nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(u_r dofs (uint32), gradient factors) of cells with the node indices ``nodes``
        (n, 3)."""
        nodes = np.ascontiguousarray(nodes)
        g = np.empty((nodes.shape[0], 5))
        gradient_factors(nodes, self.xy, g, self.geometry.plane)
        return np.ascontiguousarray(2 * nodes.astype(np.int64), dtype=np.uint32), g

    def _expressions(self, material):
        from dolfinx import fem

        from .forms import stress_components

        if self._u_fn is None:
            self._u_fn = fem.Function(self.model.V)
        comps = stress_components(self._u_fn, material, self.geometry)
        points = np.array([[1.0 / 3.0, 1.0 / 3.0]])
        return [fem.Expression(comps[name], points) for name in STRESS_NAMES]

    def evaluate(self, u: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Stresses (Pa) of the owned cells for the local displacement ``u`` (ghosts current),
        into ``out`` (5, n_owned_cells) if given; the extremes into :attr:`peaks`."""
        values = self.values if out is None else out
        bound = self._bound
        if bound is not None and u is bound[0] and values is bound[1]:
            bound[2](*bound[3])
            return values
        if self._single:
            _, dofs, g, _, lame, (first, _) = self._kernel[0]
            args = (dofs, g, u, lame[0], lame[1], self._no_plastic, first, values, self.peaks)
            if bound is None and contiguous_float64(u, 1) and contiguous_float64(values, 2):
                # the first call binds the compiled entry to these arrays (an output
                # loop's, which it then finds again); the arrays' types are checked here,
                # since an entry takes another layout or ndim unchecked
                self._bound = (u, values, direct(isotropic_stress_range, *args), args)
            isotropic_stress_range(*args)
            return values
        eps_p = self._no_plastic
        for cells, dofs, g, D, lame, run in self._kernel:
            if lame is not None and run is not None:
                isotropic_stress_range(dofs, g, u, lame[0], lame[1], eps_p, run[0], values,
                                       self._no_peaks)
                continue
            if lame is None:
                cell_stress(dofs, g, u, D, eps_p, cells, values)
            else:
                isotropic_cell_stress(dofs, g, u, lame[0], lame[1], eps_p, cells, values)
            _von_mises(values, cells, run)
        for cells, force, run in self._points:
            point_mean_stress(force.point_stresses(u).sigma, force.geometry.w, cells, values)
            _von_mises(values, cells, run)
        for (cells, force), heat in zip(self._finite, self._has_temperature):
            sig, self.finite_eps_p[cells], temp = force.frame_values(u)  # (rr, tt, zz, rz)
            if heat:
                self.finite_temperature[cells] = temp
            values[0, cells], values[1, cells] = sig[:, 0], sig[:, 2]
            values[2, cells], values[3, cells] = sig[:, 1], sig[:, 3]
            von_mises_cells(values, cells)
        for cells, g, D, eps in self._quads:
            from .q1 import mean_strain

            mean_strain(g.dofs, g.dNdR, g.dNdZ, g.N, g.inv_R, g.w, u, eps)
            sigma = eps @ D.T  # (rr, tt, zz, rz)
            values[0, cells], values[1, cells] = sigma[:, 0], sigma[:, 2]
            values[2, cells], values[3, cells] = sigma[:, 1], sigma[:, 3]
            von_mises_cells(values, cells)
        if self._ufl:
            self._u_fn.x.array[:] = u
            for cells, exprs in self._ufl:
                for k, expr in enumerate(exprs):
                    values[k, cells] = eval_expression(expr, self.model.mesh, cells)[:, 0]
        stress_peaks(values[_VM], values[_ZZ], self.peaks)
        return values


def _von_mises(values: np.ndarray, cells: np.ndarray, run: tuple[int, int] | None) -> None:
    """values[4] = von Mises of values[0:4] (Pa) on ``cells`` (the range ``run`` if given)."""
    if run is None:
        von_mises_cells(values, cells)
    else:
        a, b = run
        von_mises_rows(values[0, a:b], values[1, a:b], values[2, a:b], values[3, a:b],
                       values[4, a:b])


def _range(cells: np.ndarray) -> tuple[int, int] | None:
    """(first, end) when the sorted ``cells`` are first, first + 1, ..., end - 1; else None."""
    if cells.size and cells[-1] - cells[0] + 1 == cells.size:
        return int(cells[0]), int(cells[-1]) + 1
    return None


_VM, _ZZ = STRESS_NAMES.index("von_mises"), STRESS_NAMES.index("sigma_zz")
