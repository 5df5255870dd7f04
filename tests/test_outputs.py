"""What a run writes, checked against oracles outside the writer.

* fields.xdmf is read here with ElementTree and h5py, not with the writer's
  reader: one temporal collection, one grid per output time from t = 0 to the
  end time, every piece holding every array; the pieces hold the mesh's cells
  once: their ring volumes sum(2 pi r_c A) add up to the bodies' exact volume
  pi a^2 (L_s + L_t) (2 pi r_c A is exact for a triangle, so the only error is
  round-off), whatever the number of ranks.
* The cell values read back equal the probes of history.csv at the same step
  to round-off (both are the DG0 value of the cell, computed on two paths: the
  writer's cell loop and the probe's six dofs). Round-off bounds count roundings on
  the magnitudes they round (tests/roundoff.py): a strain from nodal displacements
  rounds on E |u| / h, not on the stress.
* The compiled cell stresses equal a UFL Expression of forms.stress_components
  at the DG0 point to round-off, for a displacement field with every strain
  component (the UFL/FFCx path is the independent oracle).
* With ParaView installed (pvbatch), its default reader opens the file: every
  block holds every array at every time, the blocks hold the cells once, the
  colour range of sigma_zz is the data's range and Warp By Vector applies.
  Without pvbatch that part is skipped; the structure is checked above anyway.
"""
import math
import os
import shutil
import xml.etree.ElementTree as ET

import h5py
import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics import scenes
from impact_fenics.cell_fields import STRESS_NAMES, CellStress
from impact_fenics.compat import eval_expression
from impact_fenics.contact import FILM
from impact_fenics.simulation import Settings
from pvbatch_run import pvbatch_json
from roundoff import LIBM, rounding

RHO, E = 7850.0, 200e9
C0 = math.sqrt(E / RHO)
V0, L, A = 5.0, 0.2, 0.05
EVERY = 10
PROBES = [("s_zz", (0.0123, 0.0517), "sigma_zz"), ("s_rr", (0.0311, -0.0713), "sigma_rr"),
          ("s_tt", (0.0417, 0.1234), "sigma_tt"), ("s_rz", (0.0234, -0.0156), "sigma_rz"),
          ("vm", (0.0077, 0.0381), "von_mises"), ("uz", (0.0123, 0.0517), "u_z"),
          ("ur", (0.0456, -0.0321), "u_r")]
CELL_FIELDS = set(STRESS_NAMES) | {"body_id"}


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    base = MPI.COMM_WORLD.bcast(str(tmp_path_factory.mktemp("outputs")), root=0)
    out = os.path.join(base, "bars")
    sim = scenes.bar_impact(Settings(cfl=0.9, t_end=1.2 * L / C0, output_every=EVERY, out=out,
                                     quiet=True, plots=False),
                            FILM(), h=0.01, nu=0.0, v0=V0, radius=A, striker_length=L,
                            target_length=L, structured=True, observe=None)
    for name, point, quantity in PROBES:
        sim.add_probe(name, point, quantity)
    summary = sim.run()
    return out, sim, summary


def _item(item, base):
    """An XDMF DataItem (HDF, Xdmf3's hyperslab of one, or an XDMF HyperSlab) as an array,
    read with h5py."""
    if item.get("ItemType") == "HyperSlab":
        sel, src = item.findall("DataItem")
        start, stride, count = np.array(sel.text.split(), dtype=int).reshape(3, -1)
        name, _, ds = src.text.strip().partition(":")
        with h5py.File(os.path.join(base, name), "r") as f:
            data = f[ds][tuple(slice(a, a + s * c, s) for a, s, c in zip(start, stride, count))]
    else:  # 'file:/path', or Xdmf3's hyperslab 'file:/path|start:stride:count:shape'
        source, _, slab = item.text.strip().partition("|")
        name, _, ds = source.partition(":")
        index = ...
        if slab:
            start, stride, count, shape = (np.array(p.split(), dtype=int) for p in slab.split(":"))
            index = tuple(slice(a, a + s * c, s) for a, s, c in zip(start, stride, count))
            with h5py.File(os.path.join(base, name), "r") as f:
                assert f[ds].shape == tuple(shape)  # the dataset the XML declares
        with h5py.File(os.path.join(base, name), "r") as f:
            data = f[ds][index]
    return data.reshape([int(d) for d in item.get("Dimensions").split()])


def _frames(out):
    """[(time, [piece: {points, cells, arrays: {name: (center, values)}}])] of fields.xdmf."""
    root = ET.parse(os.path.join(out, "fields.xdmf")).getroot()
    series = root.findall("Domain/Grid")
    assert len(series) == 1 and series[0].get("CollectionType") == "Temporal"
    frames = []
    for step in series[0].findall("Grid"):
        assert step.get("CollectionType") == "Spatial"
        pieces = []
        for piece in step.findall("Grid"):
            arrays = {a.get("Name"): (a.get("Center"), _item(a.find("DataItem"), out))
                      for a in piece.findall("Attribute")}
            pieces.append({"points": _item(piece.find("Geometry/DataItem"), out),
                           "cells": _item(piece.find("Topology/DataItem"), out).astype(int),
                           "arrays": arrays})
        frames.append((float(step.find("Time").get("Value")), pieces))
    return frames


def test_one_grid_per_time_with_every_field(run):
    out, sim, summary = run
    frames = _frames(out)
    times = np.array([t for t, _ in frames])
    n = summary["n_steps"]
    expected = [k * sim.settings.dt for k in range(0, n, EVERY)] + [n * sim.settings.dt]
    # the writer's time is the step times dt, written with repr(): the same doubles
    assert np.array_equal(times, sorted(set(expected)))  # last = end time
    for _, pieces in frames:
        assert len(pieces) == MPI.COMM_WORLD.size
        for p in pieces:
            names = set(p["arrays"])
            assert names == {"displacement", "velocity"} | CELL_FIELDS
            for key in ("displacement", "velocity"):
                center, values = p["arrays"][key]
                assert center == "Node" and values.shape == (p["points"].shape[0], 3)
                assert np.all(values[:, 2] == 0.0)  # padded for Warp By Vector
            for key in CELL_FIELDS:
                center, values = p["arrays"][key]
                assert center == "Cell" and values.shape == (p["cells"].shape[0],)


def test_pieces_hold_the_cells_once(run):
    out, sim, summary = run
    _, pieces = _frames(out)[-1]
    volume, n_cells = 0.0, 0
    for p in pieces:
        tri = p["points"][p["cells"]]  # (cells, 3, 2)
        a, b = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
        area = 0.5 * np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
        volume += float(np.sum(2 * np.pi * tri[:, :, 0].mean(axis=1) * area))
        n_cells += p["cells"].shape[0]
        # body_id: the striker (0) below z = 0, the target (1) above
        z_c = tri[:, :, 1].mean(axis=1)
        _, body = p["arrays"]["body_id"]
        assert np.all(body[z_c < 0] == 0) and np.all(body[z_c > 0] == 1)
    assert n_cells == summary["n_cells"]
    # a triangle's area: edge vectors from coordinates up to L (their differences cancel
    # L / h of the digits, h = 0.01 m), a cross product (3), then the centroid and the
    # ring (5); the sum over the cells: one rounding each
    rel = rounding(8 * L / 0.01 + n_cells)
    assert abs(volume - np.pi * A ** 2 * 2 * L) <= rel * np.pi * A ** 2 * 2 * L


def _containing_cell(pieces, point):
    """(piece, cell, the point's barycentric coordinates in it) whose triangle contains
    ``point`` strictly (probe points avoid edges)."""
    for p in pieces:
        tri = p["points"][p["cells"]]
        a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
        det = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1])
        l1 = ((b[:, 0] - point[0]) * (c[:, 1] - point[1]) - (c[:, 0] - point[0]) * (b[:, 1] - point[1])) / det
        l2 = ((c[:, 0] - point[0]) * (a[:, 1] - point[1]) - (a[:, 0] - point[0]) * (c[:, 1] - point[1])) / det
        inside = np.flatnonzero((l1 > 1e-9) & (l2 > 1e-9) & (1 - l1 - l2 > 1e-9))
        if inside.size:
            k = int(inside[0])
            return p, k, np.array([l1[k], l2[k], 1.0 - l1[k] - l2[k]])
    raise AssertionError(f"no cell holds {point}")


def test_cell_values_match_the_probes(run):
    out, sim, summary = run
    history = sim.history.data()
    frames = _frames(out)
    u = np.empty(sim.model.n_owned)
    sim.integrator.displacement(u)
    u_max = MPI.COMM_WORLD.allreduce(float(np.abs(u).max()), op=MPI.MAX)
    checked = 0
    for name, point, quantity in PROBES:
        scale = np.abs(history[name]).max()
        assert scale > 0
        if quantity in ("u_r", "u_z"):
            # the P1 interpolation sum_a w_a u_a at the point, the weights here from the
            # cross products of the output's coordinates, the probe's from a 2x2 solve: each
            # from differences of coordinates up to L on cells of h = 0.01 m (L / h of the
            # digits cancel), about 6 roundings each, then 3 products and 2 sums on the
            # nodal values
            bound = None
        else:  # each path: a strain from 6 dofs (rounding on E |u| / h), the stress, von
            # Mises with a sqrt: about 24 roundings
            bound = rounding(2 * (24 + LIBM), E * u_max / 0.01)
        for t, pieces in frames[1:]:  # history rows start after the first step
            row = np.flatnonzero(history["time"] == t)  # both n dt (above)
            assert row.size == 1
            p, cell, w = _containing_cell(pieces, point)
            if quantity in ("u_r", "u_z"):
                nodal = p["arrays"]["displacement"][1][p["cells"][cell], "u_r u_z".split().index(quantity)]
                value = float(w @ nodal)
                bound_t = rounding(2 * 6 * L / 0.01 + 5, float(np.abs(nodal).max()))
            else:
                value = p["arrays"][quantity][1][cell]
                bound_t = bound
            assert abs(value - history[name][row[0]]) <= bound_t, (name, t)
            checked += 1
    assert checked == len(PROBES) * (len(frames) - 1)


def test_history_rows_one_per_step(run):
    out, sim, summary = run
    h = np.genfromtxt(os.path.join(out, "history.csv"), delimiter=",", names=True)
    with open(os.path.join(out, "history.csv")) as f:
        header = f.readline().strip().split(",")
    assert len(header) == len(set(header))  # no duplicated columns
    assert np.array_equal(h["step"], np.arange(1, summary["n_steps"] + 1))
    assert np.array_equal(h["time"], h["step"] * sim.settings.dt)  # n dt, all 17 digits
    from impact_fenics.output import read_pairs

    # per-pair rows after the steps n = 0, k, 2k, ... (k = pairs_every) and the last one,
    # the state of step n + 1: the history's rows there
    pairs = read_pairs(os.path.join(out, "contact_pairs.h5"))
    k, n_steps = sim.settings.pairs_every, summary["n_steps"]
    rows = np.union1d(np.arange(0, n_steps, k), [n_steps - 1])
    assert np.array_equal(pairs["step"], h["step"][rows])
    # the total is the pairs' forces (all compressive) summed in another order: a
    # rounding a pair
    n_pairs = pairs["force"].shape[1]
    assert np.allclose(pairs["force"].sum(axis=1), h["contact_force"][rows], rtol=0,
                       atol=rounding(n_pairs, np.abs(h["contact_force"]).max()))


def test_cell_stress_equals_the_ufl_expression():
    """A displacement with every strain component (u_r = a r + b z^2, u_z = c z + d r z +
    e r^2): the compiled cell stresses against the UFL Expression at the DG0 point, to
    round-off (the kernel sums the same terms in another order: lambda tr(eps) + 2 mu eps
    for an isotropic D; each path a strain from 6 dofs, rounded on E |u| / h, and the
    stress: about 24 roundings)."""
    from dolfinx import fem

    from impact_fenics.forms import stress_components

    sim = scenes.bar_impact(Settings(dt=1e-7, n_steps=1, quiet=True), FILM(), h=0.01, nu=0.3,
                            radius=A, striker_length=L, target_length=L, structured=True,
                            observe=None)
    model = sim.model
    u = fem.Function(model.V)
    u.interpolate(lambda x: np.vstack([1e-3 * x[0] + 2e-3 * x[1] ** 2,
                                       -1e-3 * x[1] + 3e-3 * x[0] * x[1] + 4e-3 * x[0] ** 2]))
    u.x.scatter_forward()
    u_max = MPI.COMM_WORLD.allreduce(float(np.abs(u.x.array).max()), op=MPI.MAX)
    values = CellStress(model).evaluate(u.x.array)
    n_cells = model.mesh.topology.index_map(2).size_local
    points = np.array([[1.0 / 3.0, 1.0 / 3.0]])
    cells = np.arange(n_cells, dtype=np.int32)
    for body in model.bodies.values():
        comps = stress_components(u, body.material, model.geometry)
        mine = np.intersect1d(model.tmesh.cells(body.name), cells).astype(np.int32)
        for k, name in enumerate(STRESS_NAMES):
            ref = eval_expression(fem.Expression(comps[name], points), model.mesh, mine)[:, 0]
            scale = body.material.E * u_max / 0.01  # h = 0.01 m
            assert np.abs(values[k, mine] - ref).max(initial=0.0) <= rounding(48, scale), name


def test_isotropic_cell_stress_is_d_times_the_elastic_strain():
    """The isotropic kernel (lambda tr(eps) I + 2 mu eps, the shear taken as 2 eps_rz)
    against sigma = D (eps - eps_p) with the 4x4 D of the same material, with a plastic
    strain to subtract and cells out of order: the same sum in another order, so equal to
    round-off: a strain from 6 dofs and a plastic strain (8 roundings), the stress from it
    (4 terms of D, or lambda tr + 2 mu: 4 more), on |D| times the largest strain term."""
    from impact_fenics.cell_fields import (cell_stress, isotropic_cell_stress,
                                           isotropic_lame, isotropic_stiffness)

    rng = np.random.default_rng(7)
    n_cells, n_nodes = 400, 250
    dofs = (2 * rng.integers(0, n_nodes, (n_cells, 3))).astype(np.uint32)  # u_r dofs
    g = rng.standard_normal((n_cells, 5)) * 50.0  # inverse Jacobians of ~2 cm cells (1/m)
    u = rng.standard_normal(2 * n_nodes) * 1e-4
    eps_p = rng.standard_normal((n_cells, 4)) * 1e-3
    cells = rng.permutation(n_cells).astype(np.int64)
    D = isotropic_stiffness(1.15e11, 7.7e10)
    lame = isotropic_lame(D)
    assert lame is not None and isotropic_lame(D + np.diag([0.0, 0.0, 0.0, 1e9])) is None
    ref, got = np.zeros((5, n_cells)), np.zeros((5, n_cells))
    for plastic in (eps_p, np.empty((0, 4))):
        cell_stress(dofs, g, u, D, plastic, cells, ref)
        isotropic_cell_stress(dofs, g, u, *lame, plastic, cells, got)
        strain = 6 * np.abs(g).max() * np.abs(u).max() + np.abs(plastic).max(initial=0.0)
        assert np.abs(got[:4] - ref[:4]).max() <= rounding(2 * 12, np.abs(D).max() * strain)


def test_stress_range_is_the_kernels_one_by_one():
    """The one-call kernel of a range of cells (stresses, von Mises, the peaks) against
    the isotropic cell kernel, the von Mises rows and the peaks called one by one: the
    same operations on the same numbers, so the same floats exactly, with and without a
    plastic strain, for a range in the middle of the cells (the peaks then over every
    cell) and with the peaks left out (an empty array)."""
    from impact_fenics.cell_fields import (isotropic_cell_stress, isotropic_stress_range,
                                           stress_peaks, von_mises_rows)

    rng = np.random.default_rng(11)
    n_all, first, n, n_nodes = 300, 40, 200, 180
    dofs = (2 * rng.integers(0, n_nodes, (n, 3))).astype(np.uint32)
    g = rng.standard_normal((n, 5)) * 50.0  # inverse Jacobians of ~2 cm cells (1/m)
    u = rng.standard_normal(2 * n_nodes) * 1e-4
    lmbda, two_mu = 1.15e11, 1.54e11  # steel (Pa)
    for eps_p in (rng.standard_normal((n, 4)) * 1e-3, np.empty((0, 4))):
        ref = rng.standard_normal((5, n_all)) * 1e8  # the cells outside the range (Pa)
        got = ref.copy()
        end = first + n
        isotropic_cell_stress(dofs, g, u, lmbda, two_mu, eps_p,
                              np.arange(first, end, dtype=np.int64), ref)
        von_mises_rows(ref[0, first:end], ref[1, first:end], ref[2, first:end],
                       ref[3, first:end], ref[4, first:end])
        peaks_ref, peaks = np.zeros(3), np.zeros(3)
        stress_peaks(ref[4], ref[1], peaks_ref)
        isotropic_stress_range(dofs, g, u, lmbda, two_mu, eps_p, first, got, peaks)
        assert np.array_equal(got, ref) and np.array_equal(peaks, peaks_ref)
        got[:, first:end] = 0.0  # without the peaks: the range written again, alone
        isotropic_stress_range(dofs, g, u, lmbda, two_mu, eps_p, first, got, np.empty(0))
        assert np.array_equal(got, ref)


def test_paraview_default_reader_sees_every_array(run):
    out, sim, summary = run
    result = None
    if MPI.COMM_WORLD.rank == 0:
        result = pvbatch_json(os.path.join(out, "fields.xdmf"))
    result = MPI.COMM_WORLD.bcast(result, root=0)
    if result is None:
        pytest.skip("pvbatch (ParaView) is not installed: the structure is checked from the files")
    frames = _frames(out)
    # times: the XML's text read by ParaView and printed as JSON (at most one rounding)
    assert np.allclose(result["times"], [t for t, _ in frames], rtol=rounding(1), atol=0)
    for step, (_, pieces) in zip(result["steps"], frames):
        assert sum(b["cells"] for b in step["blocks"]) == summary["n_cells"]
        for block in step["blocks"]:
            arrays = block["arrays"]
            assert set(arrays) == {"displacement", "velocity"} | CELL_FIELDS
            assert arrays["displacement"]["components"] == 3
            assert all(arrays[k]["where"] == "cell" for k in CELL_FIELDS)
        # the values ParaView read are the file's (its ranges against h5py's)
        zz = np.concatenate([p["arrays"]["sigma_zz"][1] for p in pieces])
        lo = min(b["arrays"]["sigma_zz"]["range"][0] for b in step["blocks"])
        hi = max(b["arrays"]["sigma_zz"]["range"][1] for b in step["blocks"])
        assert (lo, hi) == (zz.min(), zz.max())
    zz_last = np.concatenate([p["arrays"]["sigma_zz"][1] for p in frames[-1][1]])
    # the colour map spans the data (ParaView's lookup table keeps its ends after some
    # arithmetic of its own: a few roundings, 16 allowed)
    assert np.allclose(result["sigma_zz_colour_range"], [zz_last.min(), zz_last.max()],
                       rtol=rounding(16), atol=0)
    assert result["warped_points"] == sum(p["points"].shape[0] for p in frames[-1][1])


# ----------------------------------------------------------------------------- the writer alone
# Frames of known values: u = (k + 1) (f_r, f_z)(x) at the nodes, every cell field a function
# of the cell's centroid plus k. Read back with h5py and ElementTree (above), each rank
# checks its own piece: the values are the same arithmetic on the same coordinates, so
# they match to round-off of the centroid (the piece's cells list the nodes in the
# model's order).

def _bar_model():
    sim = scenes.bar_impact(Settings(dt=1e-7, n_steps=1, quiet=True), FILM(), h=0.02, nu=0.3,
                            radius=A, striker_length=L, target_length=L, structured=True,
                            observe=None)
    return sim.model


def _nodal(xy, k):
    return (k + 1) * np.stack([1e-3 * xy[:, 0] * xy[:, 1], -2e-3 * xy[:, 1] ** 2], axis=1)


def _cellular(centroids, j, k):
    return (j + 1) * 1e6 * np.sin(40 * centroids[:, 0] + 7 * centroids[:, 1]) + k


def _write_frames(model, directory, n_writes, **kw):
    from impact_fenics.compat import cell_dofs
    from impact_fenics.xdmf import FieldWriter

    writer = FieldWriter(os.path.join(directory, "fields.xdmf"), model,
                         cell_fields=list(STRESS_NAMES), **kw)
    xy = model.node_xy
    n_cells = writer.n_cells
    centroids = xy[cell_dofs(model.V)[:n_cells]].mean(axis=1)
    for k in range(n_writes):
        u = _nodal(xy, k).ravel()
        v = -u
        cells = {name: _cellular(centroids, j, k) for j, name in enumerate(STRESS_NAMES)}
        writer.write(1e-6 * k, 10 * k, u, v, cells)
    return writer


def _check_frames(directory, n_frames):
    frames = _frames(directory)
    assert [t for t, _ in frames] == [1e-6 * k for k in range(n_frames)]
    for k, (_, pieces) in enumerate(frames):
        p = pieces[MPI.COMM_WORLD.rank]  # this rank's piece
        xy = p["points"]
        expected = np.zeros((xy.shape[0], 3))
        expected[:, :2] = _nodal(xy, k)
        assert np.array_equal(p["arrays"]["displacement"][1], expected)
        assert np.array_equal(p["arrays"]["velocity"][1], -expected)
        centroids = xy[p["cells"]].mean(axis=1)
        # the centroid (3 roundings of the coordinates, in the model's order or the
        # piece's), 40 r + 7 z (3 more), the sine (LIBM) times up to 5e6, plus k
        arg = 40 * np.abs(xy[:, 0]).max() + 7 * np.abs(xy[:, 1]).max()
        atol = 5e6 * (rounding(2 * 6, arg) + rounding(LIBM)) + rounding(2, 5e6 + k)
        for j, name in enumerate(STRESS_NAMES):
            ref = _cellular(centroids, j, k)
            assert np.allclose(p["arrays"][name][1], ref, rtol=0, atol=atol), (k, name)
    return frames


def test_a_killed_run_shows_the_flushed_frames_only(tmp_path_factory):
    """Frames reach the XML in flushed batches: a copy of the files taken after three writes
    with flush_every = 2 (what a killed run leaves: the third frame is in the writer's
    batch, its XML not written) reads as two frames, though the datasets hold six rows.
    (The copy reads what the OS holds: it fails if HDF5 keeps the rows in its sieve
    buffer, allocates a block's file space at the first write, in metadata not yet
    flushed, or if a flush names frames whose batch it has not written.)"""
    comm = MPI.COMM_WORLD
    base = comm.bcast(str(tmp_path_factory.mktemp("killed")), root=0)
    live, copy = os.path.join(base, "live"), os.path.join(base, "copy")
    if comm.rank == 0:
        os.makedirs(live)
        os.makedirs(copy)
    comm.barrier()
    model = _bar_model()
    writer = _write_frames(model, live, 3, n_frames=6, flush_every=2)
    writer.wait()  # the worker thread's writes handed over so far: done
    comm.barrier()
    h5 = "fields.h5" if comm.size == 1 else f"fields_p{comm.rank}.h5"
    if comm.rank == 0:  # the XML first: the rows it names were in the OS before it was
        shutil.copy(os.path.join(live, "fields.xdmf"), copy)
    comm.barrier()
    shutil.copy(os.path.join(live, h5), copy)
    comm.barrier()
    writer.close()
    comm.barrier()  # every piece closed before any rank reads them
    _check_frames(copy, 2)
    with h5py.File(os.path.join(copy, h5), "r") as f:
        assert f["/frames/points_0"].shape[0] == 6  # preallocated rows, not shown
    _check_frames(live, 3)


def _batches_of_depth(monkeypatch, depths):
    """The bars model and its writer's cell fields, with BATCH_LIMIT set so that a batch holds
    depths[rank % 2] frames: (model, names, owned cells, the piece's nodes, depth)."""
    from impact_fenics.compat import cell_dofs
    from impact_fenics.xdmf import FieldWriter

    model = _bar_model()
    names = list(STRESS_NAMES)
    n_cells = model.mesh.topology.index_map(2).size_local
    nodes = np.unique(cell_dofs(model.V)[:n_cells])
    depth = depths[MPI.COMM_WORLD.rank % 2]
    monkeypatch.setattr(FieldWriter, "BATCH_LIMIT", depth * 8 * (6 * nodes.size + len(names) * n_cells))
    return model, names, n_cells, nodes, depth


@pytest.mark.parametrize("depths", [(1, 1), (2, 3)], ids=["one_deep", "two_or_three_deep"])
def test_batched_frames_read_back_as_written(tmp_path_factory, monkeypatch, depths):
    """Frames computed in place into the writer's staging row (cell_block, as the simulation
    does), batched ``depth`` frames deep (depths[rank % 2]: ranks may differ) with depth below
    flush_every = 5, so batches reach the file between the XML's flushes; at depth 1 the
    staging row is the batch's row. n_frames = 3: at depth 2 a batch straddles the end of the
    first block. Every frame reads back exactly (bit for bit) as the arrays written, though
    the staging row was overwritten by every frame after it; the piece's nodes are the
    owned cells' nodes in local order (the layout), its cells the owned cells in order."""
    from impact_fenics.xdmf import FieldWriter

    comm = MPI.COMM_WORLD
    out = comm.bcast(str(tmp_path_factory.mktemp("batched")), root=0)
    model, names, n_cells, nodes, depth = _batches_of_depth(monkeypatch, depths)
    writer = FieldWriter(os.path.join(out, "fields.xdmf"), model, cell_fields=names,
                         flush_every=5, n_frames=3)
    assert writer.depth == depth
    stress = writer.cell_block(names)
    rng = np.random.default_rng(comm.rank)
    written = []
    for k in range(11):
        u, v = rng.standard_normal((2, 2 * model.node_xy.shape[0]))
        stress[:] = rng.standard_normal(stress.shape)
        writer.write(1e-6 * k, 10 * k, u, v, writer.cell_values)
        written.append((u, v, stress.copy()))
    writer.close()
    comm.barrier()  # every piece closed before any rank reads them
    frames = _frames(out)
    assert [t for t, _ in frames] == [1e-6 * k for k in range(11)]
    for (_, pieces), (u, v, cells) in zip(frames, written):
        p = pieces[comm.rank]
        assert np.array_equal(p["points"][:, :2], model.node_xy[nodes])
        for key, values in (("displacement", u), ("velocity", v)):
            expected = np.zeros((nodes.size, 3))
            expected[:, :2] = values.reshape(-1, 2)[nodes]
            assert np.array_equal(p["arrays"][key][1], expected), key
        for j, name in enumerate(names):
            assert np.array_equal(p["arrays"][name][1], cells[j]), name


def test_more_frames_than_announced_go_to_a_new_block(tmp_path_factory):
    """n_frames = 2 and five writes: a second block of frames (each item names its block and
    the block's declared shape, checked against the file); every frame reads back, and
    ParaView's default reader sees every array at every time across the blocks."""
    comm = MPI.COMM_WORLD
    out = comm.bcast(str(tmp_path_factory.mktemp("grown")), root=0)
    model = _bar_model()
    _write_frames(model, out, 5, n_frames=2, flush_every=3).close()
    comm.barrier()  # every piece closed before any rank reads them
    frames = _check_frames(out, 5)
    h5 = "fields.h5" if comm.size == 1 else f"fields_p{comm.rank}.h5"
    with h5py.File(os.path.join(out, h5), "r") as f:
        assert sorted(f["/frames"]) == ["cells_0", "cells_1", "points_0", "points_1"]
        assert f["/frames/cells_0"].shape[0] == 2 and f["/frames/cells_1"].shape[0] == 16
    result = pvbatch_json(os.path.join(out, "fields.xdmf")) if comm.rank == 0 else None
    result = comm.bcast(result, root=0)
    if result is None:
        pytest.skip("pvbatch (ParaView) is not installed: the files were checked with h5py")
    assert result["reader"] == "Xdmf3ReaderS"
    assert np.allclose(result["times"], [t for t, _ in frames], rtol=rounding(1), atol=0)
    for step, (_, pieces) in zip(result["steps"], frames):
        assert len(step["blocks"]) == comm.size
        for block, p in zip(step["blocks"], pieces):
            assert set(block["arrays"]) == {"displacement", "velocity"} | CELL_FIELDS
            zz = p["arrays"]["sigma_zz"][1]
            assert block["arrays"]["sigma_zz"]["range"] == [zz.min(), zz.max()]
            size = np.linalg.norm(p["arrays"]["displacement"][1], axis=1)
            assert block["arrays"]["displacement"]["components"] == 3
            assert block["points"] == p["points"].shape[0]
            # |u| of 3 components by ParaView and by numpy: 5 roundings and a sqrt each
            assert np.allclose(block["arrays"]["displacement"]["range"], [size.min(), size.max()],
                               rtol=rounding(2 * (5 + LIBM)), atol=0)


@pytest.mark.parametrize("depths", [(1, 1), (2, 3), (5, 5)], ids=["one_deep", "two_or_three_deep",
                                                                   "flush_deep"])
def test_worker_thread_files_are_the_synchronous_files_byte_for_byte(tmp_path_factory,
                                                                      monkeypatch, depths):
    """The same frames written twice, by h5py on the caller's thread (FieldWriter.ASYNC off)
    and by the worker thread's os.pwrite at the datasets' offsets: every file (each rank's
    .h5 and the .xdmf) is byte for byte the same. The oracle is HDF5 itself: the raw
    bytes land where its hyperslab writes put them, in its byte order. Depths as in the
    batched test, and a batch as deep as a flush (the bars' case); n_frames = 3 and 11
    writes: a batch straddles the first block's end, and the second block (never filled
    with zeros) holds rows not written."""
    from impact_fenics.xdmf import FieldWriter

    comm = MPI.COMM_WORLD
    base = comm.bcast(str(tmp_path_factory.mktemp("async_bytes")), root=0)
    model, names, n_cells, _, depth = _batches_of_depth(monkeypatch, depths)
    rng = np.random.default_rng(comm.rank)
    frames = [(rng.standard_normal((2, 2 * model.node_xy.shape[0])),
               rng.standard_normal((len(names), n_cells))) for _ in range(11)]
    for threaded in (False, True):
        monkeypatch.setattr(FieldWriter, "ASYNC", threaded)
        out = os.path.join(base, f"threaded_{threaded}")
        if comm.rank == 0:
            os.makedirs(out)
        comm.barrier()
        writer = FieldWriter(os.path.join(out, "fields.xdmf"), model, cell_fields=names,
                             flush_every=5, n_frames=3)
        assert writer.depth == depth and writer.asynchronous == threaded
        stress = writer.cell_block(names)
        for k, ((u, v), cells) in enumerate(frames):
            stress[:] = cells
            writer.write(1e-6 * k, 10 * k, u, v, writer.cell_values)
        writer.close()
    comm.barrier()  # every file closed before any rank reads them
    h5 = "fields.h5" if comm.size == 1 else f"fields_p{comm.rank}.h5"
    for name in [h5] + (["fields.xdmf"] if comm.rank == 0 else []):
        with open(os.path.join(base, "threaded_False", name), "rb") as f:
            synchronous = f.read()
        with open(os.path.join(base, "threaded_True", name), "rb") as f:
            threaded = f.read()
        assert len(threaded) == len(synchronous) and threaded == synchronous, name
    assert len(_frames(os.path.join(base, "threaded_True"))) == 11


def test_a_worker_write_error_stops_the_writes(tmp_path_factory, monkeypatch):
    """The worker thread's write fails (its descriptor of the .h5 file swapped for a read-only
    one under it, on rank 0: EBADF, as a disk-full ENOSPC or an EIO would come): the
    next write, flush or close on the caller's thread raises OSError, one line naming
    the file and the cause, on every rank at the same call (the others say a rank
    failed: none waits for it); close then closes the files without a collective flush,
    and the XML names only the frames of the flush before, which read back as written."""
    import errno

    from impact_fenics.xdmf import FieldWriter

    comm = MPI.COMM_WORLD
    out = comm.bcast(str(tmp_path_factory.mktemp("worker_error")), root=0)
    model = _bar_model()
    monkeypatch.setattr(FieldWriter, "ASYNC", True)  # (the thread even with no core free)
    writer = _write_frames(model, out, 2, n_frames=6, flush_every=2)
    assert writer.asynchronous
    writer.wait()
    h5 = "fields.h5" if comm.size == 1 else f"fields_p{comm.rank}.h5"
    read_only = os.open(os.path.join(out, h5), os.O_RDONLY)
    if comm.rank == 0:
        os.dup2(read_only, writer._fd)
    from impact_fenics.compat import cell_dofs

    xy = model.node_xy
    centroids = xy[cell_dofs(model.V)[: writer.n_cells]].mean(axis=1)
    with pytest.raises(OSError) as info:
        for k in range(2, 12):
            u = _nodal(xy, k).ravel()
            writer.write(1e-6 * k, 10 * k, u, -u,
                         {name: _cellular(centroids, j, k) for j, name in enumerate(STRESS_NAMES)})
        writer.flush()
    message = str(info.value)
    assert "\n" not in message
    if comm.rank == 0:
        assert info.value.errno == errno.EBADF and h5 in message, message
    else:
        assert "another rank" in message, message
    writer.close()  # (no collective flush after a failure: this returns on every rank)
    os.close(read_only)
    comm.barrier()
    _check_frames(out, 2)


def test_linear_cell_stress_is_the_weighted_mean_of_its_point_stresses():
    """A linear body's cell stress (D eps at the centroid) is the mean of the stresses at the
    three points of the stiffness rule weighted by w_q |J| 2 pi r_q, the output of a
    path-dependent body: computed here from the rule's points and P1 shape functions
    with numpy, for a displacement with every strain component and cells on the axis.
    Round-off: 64 eps of the largest stress (some 30 rounded operations a side)."""
    from impact_fenics.compat import cell_dofs

    sim = scenes.bar_impact(Settings(dt=1e-7, n_steps=1, quiet=True), FILM(), h=0.01, nu=0.3,
                            radius=A, striker_length=L, target_length=L, structured=False,
                            observe=None)
    model = sim.model
    xy = model.node_xy
    u = np.zeros(2 * xy.shape[0])
    u[0::2] = 1e-3 * xy[:, 0] + 2e-3 * xy[:, 0] * xy[:, 1] ** 2
    u[1::2] = -1e-3 * xy[:, 1] + 3e-3 * xy[:, 0] * xy[:, 1] + 4e-3 * xy[:, 0] ** 2
    values = CellStress(model).evaluate(u)
    n_cells = model.mesh.topology.index_map(2).size_local
    nodes = cell_dofs(model.V)[:n_cells]
    X, U = xy[nodes], u.reshape(-1, 2)[nodes]  # (n, 3, 2)
    ref = np.array([[1 / 6, 1 / 6], [2 / 3, 1 / 6], [1 / 6, 2 / 3]])  # the rule: weights 1/6
    N = np.column_stack([1 - ref.sum(axis=1), ref])  # (points, nodes)
    J = np.stack([X[:, 1] - X[:, 0], X[:, 2] - X[:, 0]], axis=2)  # dx_a / dxi_b
    grad_u = np.einsum("nia,nab->nib", np.stack([U[:, 1] - U[:, 0], U[:, 2] - U[:, 0]], 2),
                       np.linalg.inv(J))  # du_i / dx_b (constant)
    r_q = N @ X[:, :, 0].T  # (points, n)
    ur_q = N @ U[:, :, 0].T
    w = np.abs(np.linalg.det(J)) / 6 * 2 * np.pi * r_q
    material = next(iter(model.bodies.values())).material
    assert all(b.material == material for b in model.bodies.values())
    lam, mu = material.lmbda, material.mu
    e_rr, e_zz = grad_u[:, 0, 0], grad_u[:, 1, 1]
    e_rz = 0.5 * (grad_u[:, 0, 1] + grad_u[:, 1, 0])
    e_tt = ur_q / r_q
    tr = e_rr + e_zz + e_tt
    mean = lambda s: (w * s).sum(axis=0) / w.sum(axis=0)  # noqa: E731
    expected = {"sigma_rr": mean(lam * tr + 2 * mu * e_rr), "sigma_zz": mean(lam * tr + 2 * mu * e_zz),
                "sigma_tt": mean(lam * tr + 2 * mu * e_tt), "sigma_rz": mean(2 * mu * e_rz + 0 * r_q)}
    scale = MPI.COMM_WORLD.allreduce(max(float(np.abs(v).max()) for v in expected.values()),
                                     op=MPI.MAX)
    for k, name in enumerate(STRESS_NAMES[:4]):
        assert np.abs(values[k, :n_cells] - expected[name]).max() <= 64 * np.finfo(float).eps * scale, name
    on_axis = np.abs(X[:, :, 0]).min(axis=1) < 1e-12 * A  # (r = +-1e-19 there: mesh round-off)
    assert MPI.COMM_WORLD.allreduce(int(on_axis.sum())) > 0
