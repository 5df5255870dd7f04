"""A tie: a deformable face bonded to a rigid part (a button brazed on a bit, a platen).

The tie is DME's rigid cluster (:mod:`.dme`, case 1) with release switched off: every
tied node joins the part at every step, whatever its predicted gap or velocity. That is
the exact velocity-level elimination of the two-sided constraint u_i = u_p + b_i,

    v_c = (m_p v~_p + sum m_i v~_i) / (m_p + sum m_i),   v_i = v_p = v_c,
    u_p = u_p^n + h_{n+1/2} v_c,                           u_i = u_p + b_i,

(a fixed or prescribed part keeps its own v~_p: its mass is infinite). The momentum of
the part and the tied nodes is conserved to round-off, and each node's reaction is
f_i = m_i (v~_i - v_c) / h_n (N, compressive-positive, as a contact force), booked by
the set's ledger like one. The offset b_i is the displacement offset, 0 at set-up
(u_i = u_p = 0), not the contact gap: the nodes never jump, u_i^{n+1} = u_i^n +
h_{n+1/2} v_i^{n+1/2} exactly. The tied nodes start at the part's velocity
(:meth:`Tie.start`) and their u_r (x in plane strain) is fixed (:func:`tie_radial_dofs`,
the run's fixed dofs): a bonded face does not slide. Derivation and ledger:
docs/one_loop.md, "A tie".
"""
from __future__ import annotations

import numpy as np
from numba import njit

from ..errors import InputError
from .dme import _join, _merged_velocity
from .pairing import Constraints, face_nodes, rigid_face


class Tie:
    """The tie's method on a rigid face's contact set (:class:`.interface.ContactSet`):
    every node joins the part every step. No friction, re-pairing, other set of its part,
    or deformable partner (refused in one line)."""

    name = "tie"
    jumps = False  # u_i = u_p + b_i with b_i = 0 at every step: no position jump

    def __init__(self) -> None:
        self.info: dict[str, float | str] = {}
        self.members: np.ndarray | None = None

    def setup(self, c) -> None:
        """Check the set (a rigid face, the part moving along z only, the tied nodes' u_r
        fixed in the run) and make the constraint order (every constraint, every step)."""
        if getattr(c, "rigid", None) is None:
            raise InputError(f"tie '{c.constraints.names[0]}'/'{c.constraints.names[1]}': a "
                             "tie binds a face to a rigid part, not two deformable bodies "
                             "(use a contact set, or merge the bodies in one mesh)")
        if c.rigid.sideways:
            raise InputError(f"tie to rigid body '{c.rigid.name}': a tied part moves along "
                             "z only (no sideways velocity or force)")
        if getattr(self, "members", None) is not None:  # checked: a new step's setup
            return
        self.members = np.arange(c.n, dtype=np.int32)
        held = c.integrator.free[c._local - 1]  # the nodes' first component (r, x) dofs
        if c.comm.allreduce(int(np.count_nonzero(held))):
            raise InputError(f"tie '{c.constraints.names[0]}'/'{c.rigid.name}': the tied nodes' "
                             f"{c.integrator.model.geometry.axes[0]} must be fixed (a bonded "
                             "face does not slide): give the run tie_radial_dofs(...) among its "
                             "fixed dofs (a scene's [[tie]] does)")

    def start(self, c) -> None:
        """Set-up, once, before the set reads v^0: the tied nodes move at the part's
        velocity (otherwise step 1 would be a plastic impact of the face on the part)."""
        c.integrator.v_owned[c._local] = c.rigid.v

    def correct(self, c) -> None:
        _tie(self.members, c.b, c.nodes, c.body, c.side, c.mass, c.m_over_dt, c.dt, c.u_now,
             c.u, c.v, c.force, c.active)


@njit(cache=True)
def _tie(members, b, nodes, body, side, mass, m_over_dt, dt, u_now, u, v, force, active):
    """Every tied node and the part move as one (DME's cluster, all members, no release):
    the momentum average v_c, the part to u_p^n + dt v_c, each node onto it; its reaction
    m_i (side (v~_i - v_c)) / h_n (N)."""
    k = members.size
    v_c = _merged_velocity(members, k, nodes, body, mass, v)
    _join(members, k, b, nodes, body, side, m_over_dt, dt, u_now, v_c, u, v, force, active)


def tie_face(model, surface: str, radius: float, body_name: str) -> Constraints:
    """The tie's constraints: the nodes of ``surface`` with |r| <= radius (m; the
    half-width in plane strain), as a rigid ``[[contact]]`` face selects them, under the
    rigid part ``body_name`` above them, each with offset b = 0 (m)."""
    return rigid_face(model, surface, radius, body_name)


def tie_radial_dofs(model, surface: str, radius: float) -> np.ndarray:
    """The owned dofs of u_r (x in plane strain) of the nodes the tie ``tie_face`` binds:
    give them to the run as fixed dofs (a bonded face does not slide)."""
    return face_nodes(model, surface, radius, 0)
