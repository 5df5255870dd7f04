"""A run's tables: history.csv (a row per history step: probes, contact columns), energy.csv
(a row per output step: the ledger's columns, z momenta) and the per-pair rows of
contact_pairs.h5; output.py writes them.

Units: s, m, N, J, kg m/s.
"""
from __future__ import annotations

import os
from typing import Callable, Iterable

import numpy as np
from mpi4py import MPI

from . import output
from .worker import spare_core

# the energy table's columns after step and time (J; balance_error_rel: -), then the
# z momenta (momentum_columns)
ENERGY_COLUMNS = ("kinetic", "strain", "total", "external_work", "contact_work",
                  "activation_loss", "plastic_work", "deformation_work", "balance_error",
                  "balance_error_rel", "work_gap")


def momentum_columns(bodies: Iterable[str], contacts: list) -> list[str]:
    """The z momentum columns (kg m/s): the total, then per body and per moving rigid body
    of the contact sets (a fixed or prescribed one takes any impulse and keeps none); then the x
    momentum M V of each rigid body that slides (plane strain, docs/friction.md 11)."""
    names = list(bodies) + [c.rigid.name for c in contacts if c.moving_rigid is not None
                            and c.rigid.prescribed is None]
    sliding = [c.rigid.name for c in contacts
               if c.moving_rigid is not None and c.rigid.slides]
    return (["momentum_z"] + [f"momentum_z_{n}" for n in names]
            + [f"momentum_x_{n}" for n in sliding])


def open_tables(staging: str | None, probes, contacts: list, integ, dt: float,
                momentum: list[str], pair_rows: int,
                comm: MPI.Comm) -> tuple[dict, Callable[[], None], list]:
    """History, energy and per-pair tables (on disk with an output directory ``staging``,
    written in blocks; in memory without one), the history row's filler
    (:func:`history_filler` of ``integ``'s state, dt in s) and the per-pair tables rank 0
    writes, [(contact set, PairHistory)] (``pair_rows``: their rows at most).

    A history row is raw: the probes' dofs this rank owns (summed over the ranks once
    per block), then step, time, dt and the contact columns; the block's finish turns
    the dofs into the probe values. ``momentum``: the energy table's momentum columns."""
    path = (lambda name: os.path.join(staging, name)) if staging else (lambda name: None)
    cols = ["step", "time", "dt"] + (probes.names if probes else [])
    for k, c in enumerate(contacts):
        tag = f"c{k}_" if len(contacts) > 1 else ""
        # the total contact force (N); on a rigid body it is the force on that body
        force = f"{c.rigid.name}_force" if c.rigid is not None else "contact_force"
        cols += [f"{tag}n_active", f"{tag}{force}", f"{tag}min_gap"]
        if c.moving_rigid is not None:  # (a fixed part's would be zeros)
            cols += [f"{tag}{c.rigid.name}_u", f"{tag}{c.rigid.name}_v"]
            if c.rigid.prescribed is not None:  # the contact's z force on it (N)
                cols += [f"{tag}{c.rigid.name}_reaction"]
            if c.rigid.slides:  # its x dof (plane strain)
                cols += [f"{tag}{c.rigid.name}_u_x", f"{tag}{c.rigid.name}_v_x"]
        cols += [f"{tag}cpu_detection", f"{tag}cpu_solve", f"{tag}cpu_update"]
        if getattr(c, "friction", None) is not None:  # its tangential pass's stats
            cols += [f"{tag}{name}" for name, _ in c.friction.history_columns]
    n_raw = probes.n_raw if probes else 0
    n_probes = len(probes.names) if probes else 0
    block = 256

    out = np.empty((block, len(cols)))

    def finish(raw: np.ndarray) -> np.ndarray:
        o = out[: raw.shape[0]]
        o[:, :3] = raw[:, n_raw: n_raw + 3]  # step, time, dt
        if probes is not None:
            probes.values(raw[:, :n_raw], o[:, 3: 3 + n_probes])
        o[:, 3 + n_probes:] = raw[:, n_raw + 3:]
        return o

    tables = {"history": output.Table(path("history.csv"), cols, comm, block,
                                      raw_columns=n_raw + len(cols) - n_probes,
                                      summed=n_raw, finish=finish,
                                      asynchronous=spare_core(comm)),
              "energy": output.Table(path("energy.csv"), ["step", "time"] + list(ENERGY_COLUMNS)
                                     + momentum, comm, 16)}
    history_row = history_filler(tables["history"], probes, n_raw, integ, dt, contacts)
    # per-pair rows (rank 0 writes them): every pairs_every steps and after the last
    pair_tables = []
    for k, c in enumerate(contacts):
        name = "contact_pairs.h5" if len(contacts) == 1 else f"contact_pairs_{k}.h5"
        if staging:
            friction = getattr(c, "friction", None)
            tables[f"pairs{k}"] = output.PairHistory(path(name), c.r, comm, rows=pair_rows,
                                                     tangential=friction is not None,
                                                     axis=c.integrator.model.geometry.axes[0])
            if comm.rank == 0:
                pair_tables.append((c, tables[f"pairs{k}"]))
                tables[f"pairs{k}"].prepare(c.committed_gap(), c.force, c.active,
                                            *(() if friction is None else
                                              (friction.lam, friction.state)))
    return tables, history_row, pair_tables


def history_filler(table: output.Table, probes, offset: int, integ, dt: float,
                   contacts: list) -> Callable[[], None]:
    """``history_row()``: one history row of the state after the step (step integ.n, time
    n dt in s, or under a varying step the sum of the steps) into ``table``'s block
    through its memoryview: no communication, no allocation, what it reads bound as
    locals (about 1 us a row with a probe and a contact set)."""
    next_row, cells = table.next_row, table.cells
    record = probes.recorder(integ.u_owned, table.flat) if probes is not None else None
    # per contact: its stats (number active, total force, smallest gap; updated in place
    # by its step), its phase times, its rigid body and its first raw column
    layout, k = [], offset + 3
    friction = []  # (its stats, their indices, its first raw column) per set with friction
    for c in contacts:
        rigid = c.moving_rigid
        slides = rigid is not None and rigid.slides
        layout.append((memoryview(c.stats), c.times, rigid, slides, k))
        k += 6 + (2 if rigid is not None else 0) + (2 if slides else 0)
        k += 1 if rigid is not None and rigid.prescribed is not None else 0
        if getattr(c, "friction", None) is not None:
            which = tuple(i for _, i in c.friction.history_columns)
            friction.append((c.friction.stats, which, k))
            k += len(which)

    step = integ.step
    constant = step.constant

    def history_row() -> None:
        j = next_row()
        if record is not None:
            record(j)
        n = integ.n
        k = j + offset
        cells[k] = float(n)
        if constant:
            cells[k + 1] = n * dt
            cells[k + 2] = dt  # the step that led to this state (constant)
        else:  # t^n, the sum of the steps, and h_{n-1/2}, the step that led to it
            cells[k + 1] = step.time(n)
            cells[k + 2] = step.h
        for stats, times, rigid, slides, k in layout:
            k += j
            cells[k] = stats[0]
            cells[k + 1] = stats[1]
            cells[k + 2] = stats[2]
            if rigid is not None:
                cells[k + 3] = rigid.u
                cells[k + 4] = rigid.v
                k += 2
                if rigid.prescribed is not None:
                    cells[k + 3] = rigid.reaction
                    k += 1
                if slides:
                    cells[k + 3] = rigid.u_x
                    cells[k + 4] = rigid.v_x
                    k += 2
            cells[k + 3] = times.detection
            cells[k + 4] = times.solve
            cells[k + 5] = times.update
        for stats, which, k in friction:
            k += j
            for i in which:
                cells[k] = stats[i]
                k += 1
    return history_row


def record_pairs(pair_tables: list, n: int, dt: float, t: float | None = None) -> None:
    """One per-pair row of every contact set of ``pair_tables`` (:func:`open_tables`'; rank 0)
    for the state of step n (time n dt, s, or ``t`` under a varying step): the committed
    gaps (m), forces (N) and active flags (and with friction the tangential forces and
    stick/slip flags)."""
    if t is None:
        t = n * dt
    for c, pairs in pair_tables:
        friction = getattr(c, "friction", None)
        if friction is None:
            pairs.record(n, t, c.committed_gap(), c.force, c.active)
        else:  # with the tangential forces (N) and sets
            pairs.record(n, t, c.committed_gap(), c.force, c.active, friction.lam,
                         friction.state)
