"""The tangential pass folded into the set's one compiled call of a step.

With friction on node pairs or a rigid face (the wall, a moving punch), FILM, DME and the
penalty run the normal step and the tangential pass as one call
(fused.contact_step_friction). The oracle is exact equivalence with the path it
replaces, the normal call followed by the tangential pass as a call of its own: the same
kernels in the same order on the same arrays, so at every step both, run from the same
state, leave the same numbers bit for bit. Compared on the run's own partition, so on any
number of ranks.
"""
from __future__ import annotations

import os
import types

import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics.contact.friction import Tangential
from test_friction import PUNCH_SCENE, SCENE, WALL_SCENE

COMM = MPI.COMM_WORLD


def _state(c) -> tuple:
    """Every array a step of set ``c`` writes: the owned u and v (m, m/s), the set's packed
    slots, maps, flags and scalars (the ledger: contact work, activation loss), and its
    tangential pass's slots, rows (λ_t, s_e), stick/slip flags and stats (slip work,
    tangential loss, the penalty's release loss and stored energy)."""
    integ, t = c.integrator, c.friction
    return (integ.u_owned, integ.v_owned, c._floats, c._ints, c._flags, c._misc, t.slots,
            t.rows, t.state, t.stats)


def _rigid(c) -> tuple:
    r = c.rigid
    return () if r is None else (r.u, r.v, r.wave_incident, r.wave_reflected,
                                 r.wave_delivered)


def _both_paths(c, checked: list):
    """Set ``c``'s step run twice from the same state: first with the tangential pass as
    a call of its own (the previous path), then folded; appends whether the two left
    every array of :func:`_state` and the rigid body's state bit for bit equal."""
    step, t = c.step, c.friction
    separate = types.MethodType(Tangential.step, t)

    def both() -> None:
        kept = _state(c)
        before = [a.copy() for a in kept]
        rigid_before = _rigid(c)
        t.step, t.folds = separate, False  # the pass as a call of its own
        step()
        after_old = [a.copy() for a in kept]
        rigid_old = _rigid(c)
        for a, b in zip(kept, before):
            a[...] = b
        if c.rigid is not None:
            (c.rigid.u, c.rigid.v, c.rigid.wave_incident, c.rigid.wave_reflected,
             c.rigid.wave_delivered) = rigid_before
        del t.step
        t.folds = True
        step()
        checked.append(all(np.array_equal(a, b) for a, b in zip(kept, after_old))
                       and _rigid(c) == rigid_old)
    return both


@pytest.fixture(scope="module")
def tmp(tmp_path_factory):
    path = str(tmp_path_factory.mktemp("friction_fused")) if COMM.rank == 0 else None
    return COMM.bcast(path)


@pytest.mark.parametrize("method", ["film", "dme", "penalty"])
@pytest.mark.parametrize("kind", ["pairs", "wall", "punch"])
def test_folded_pass_equals_separate_call(tmp, method, kind):
    """At every step of a run with friction (μ = 0.3 on pairs and the wall, 0.2 under the
    punch: stick and slip both present), the one call and the normal call followed by the
    tangential pass leave u, v, every slot, λ_t and flag, the ledger and the friction
    stats, and the rigid body's state bit for bit equal (exact equivalence)."""
    from impact_fenics.scene_file import build, read_scene

    if kind == "punch":
        text = PUNCH_SCENE.format(method=method, peak=200e6).replace("n_steps = 120",
                                                                     "n_steps = 60")
    else:
        text = (SCENE if kind == "pairs" else WALL_SCENE).format(
            method=method, friction="friction = 0.3", v0=5.0)
    path = os.path.join(tmp, f"fused_{kind}_{method}.toml")
    if COMM.rank == 0:
        with open(path, "w") as f:
            f.write(text)
    COMM.barrier()
    sim = build(read_scene(path), {"out": None, "quiet": True})
    sets = [c for c in sim.contacts if c.friction is not None]
    assert sets and all(c.friction.folds and c._fused is not None for c in sets)
    checked: list = []
    for c in sets:
        c.step = _both_paths(c, checked)
    sim.run()
    h = sim.history.data()
    slipped = np.asarray(h["n_slip"], dtype=float)
    assert len(checked) == len(sets) * slipped.size and all(checked)  # every step
    assert np.any(slipped > 0) and np.any(np.asarray(h["n_stick"], dtype=float) > 0)
