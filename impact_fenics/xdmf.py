"""Fields for ParaView: an XDMF time series with every field on one grid per output time.

Layout (what ``fields.xdmf`` describes):

* the mesh (triangles, or quadrilaterals for the finite-strain bodies) in
  pieces, one per MPI rank: piece p holds the cells rank p owns
  (each cell of the mesh in exactly one piece) and the nodes of those cells
  (a node on a partition boundary appears in both pieces, with the same
  values). Each rank writes its own HDF5 file (``fields.h5`` on one rank,
  ``fields_p<rank>.h5`` on more), so nothing is gathered to one rank and the
  writes run in parallel without an MPI-enabled HDF5;
* ``/mesh/geometry`` (r, z in m; x, y in plane strain), ``/mesh/topology`` (piece-local node
  indices) and the static cell fields (``body_id``) are written once and
  referenced at every time;
* at each output time one temporal step: a spatial collection of the pieces,
  each with ``displacement`` (m) and ``velocity`` (m/s) as point vectors
  padded to three components (ParaView's Warp By Vector takes them as they
  are) and every cell field (Pa for stresses) as cell scalars;
* a frame's data is one row of two datasets per block of frames,
  ``/frames/points_<b>`` (frames, 2, nodes, 3: displacement, velocity) and
  ``/frames/cells_<b>`` (frames, fields, cells), nothing created per frame
  (see Batches below for when the rows are written). The first block holds
  the run's known number of frames (``n_frames``), or as many of them as
  ``FILL_LIMIT`` bytes hold; more frames, or an unknown count (the
  finite-strain driver), add blocks, each as long as all before it (at least
  ``BLOCK``, at most the announced frames still to come), so a run stopped
  early leaves a file at most twice what it wrote. The first block is written
  with zeros when it is made, at set-up: the file's pages are then
  in the OS's cache and writing rows costs the copy, not the page faults
  (figures measured when the fill came, a frame written at a time: punch
  0.24 ms a write against 0.48, and less set-up + writes in all; bars 24 us
  against 43). Blocks added later are allocated, never filled (a fill
  would stall the loop): rows a run did not reach are in the file, as zeros or
  holes of a sparse file, but never in the XML.

Why so: an HDF5 dataset costs about 25 us to create (HDF5 1.10, whatever the
layout or property list), so a frame of seven datasets and a group cost a small
mesh's frame several times over (figures of that change: bars 0.31 ms a frame
against 0.07 ms).

Batches: HDF5 costs a write call about 5 us through h5py before any byte (a
64-byte hyperslab write, loaded machine), as much as a small mesh's frame costs in
bytes (bars: two calls a frame against ~12 us for its 69 kB), so :meth:`FieldWriter.write`
only copies the frame into an in-memory batch, ``depth`` frames deep, preallocated
at set-up: the point vectors straight from u and v, the cell fields from the
staging row (:attr:`FieldWriter.cell_values`, :meth:`FieldWriter.cell_block`:
callers compute into it, and it is free for the next frame when write returns).
``depth`` is ``flush_every``, or fewer frames when those would pass ``BATCH_LIMIT``
(1 MiB) a rank: a batch pays for a copy per frame to save calls, a gain only while
a frame's bytes cost less than the calls (the bars' 69 kB frame: 8 deep), and a
large mesh's frames go one at a time (the punch's 1.4 MB frame: 1 deep).

When the batch is full, and at every flush, its frames go to the file, each run of
consecutive rows of a block (two when the batch straddles the end of a block) as
one byte range per dataset, on a worker thread (one per writer and rank, a daemon
started at set-up and ended at close): the datasets are contiguous and their file
space allocated when made, so a run of rows is one range of the batch in memory
and one in the file (the dataset's offset, ``H5Dget_offset``, + row x bytes per
row), and the worker writes it with ``os.pwrite`` into its own descriptor of the
rank's .h5 file (float64 in memory is H5T_NATIVE_DOUBLE's little-endian IEEE in the
file: the bytes are those h5py would write, tests/test_outputs.py compares the
files byte for byte). pwrite releases the GIL, and the loop's steps between outputs
run as one compiled ``nogil`` call (step_block.py), so the bytes reach the OS while
the steps run. The batch is double: the writes fill one while the worker writes
the other (a batch is refilled only once its job is done). h5py's hyperslab writes on
the caller's thread remain where a dataset gives no offset, the file is not the
POSIX one (sec2 driver), the machine is big-endian, no core is free for the thread
(worker.spare_core: 2 ranks on 2 cores write on their own threads, measured faster),
or ``FieldWriter.ASYNC`` is False (True: the thread wherever it can be).
A failed pwrite (disk full, EIO) is kept by the worker and raised as one-line
OSError on the caller's thread at the next write, flush or close (on more ranks at
the next flush's meeting, on every rank at once, so none waits for a rank that
stopped); close then closes the files without a flush.

Figures (2 cores shared with other jobs; A/B of the same code with ASYNC off,
interleaved, medians): bars (1,198 dofs, 500 steps, 21 frames, 8 deep), 1 rank, 30
runs each while the other core was idle: loop 5.80 -> 5.55 ms (1.57 -> 1.50 x steps
x median step), its output phase 1.19 -> 0.92 ms; the write that flushes 0.13 ->
0.06 ms (left: the XML, 0.03 ms, built on the caller's thread, and the job); with
both cores busy (other jobs) no gain, 5.85 -> 5.79 ms: the worker's pwrite then
takes the loop's core; 2 ranks on the 2 cores: the same, 6.28 against 6.26 ms (no
core for the threads). Punch (22,660 dofs, 400 steps, 1 deep), other core idle: a
write 0.24 -> 0.11 ms (of which 0.05 ms the cell fields' copy from the staging row
into the batch: the worker writes the batch while the caller computes the next
frame's stresses into the staging row), loop 83.4 -> 80.9 ms (1.20 -> 1.17). Memory:
two batches and a staging row, bars 1.1 MB a rank (0.55 MB before), punch 3.7 MB
(1.4 MB before, the staging row being the batch's row): at most twice ``BATCH_LIMIT``
(or two frames, when one passes it) and a frame's cell fields.

Each attribute names its row with Xdmf3's heavy-data hyperslab,
``file.h5:/frames/cells_0|start:stride:count:shape`` in an HDF DataItem. That is
what ParaView's default reader for .xdmf (Xdmf3ReaderS, and Xdmf3ReaderT) reads;
it skips an XDMF ``ItemType="HyperSlab"`` item ("unrecognized array type": it asks
the array's type before reading it, and a HyperSlab has none until read). The
older "XDMF Reader" (Xdmf2) reads only that HyperSlab form, not the Xdmf3 one:
choose one of the Xdmf3 readers when ParaView asks. (Both forms side by side
make both readers show every array, but each reader then prints an error per
array and time: not done.) :func:`data_item` reads all three forms.

ParaView (File > Open fields.xdmf, Apply) then shows one block per piece,
every block with every array at every time; colour by sigma_zz, Warp By Vector.
A plane-strain run names its stresses for its slots (sigma_xx, sigma_yy, sigma_out,
sigma_xy: :meth:`.geometry.Geometry.public`) and says its geometry and thickness in an
Information element ``geometry`` (absent: axisymmetric).

The XML is appended, never rewritten: rank 0 keeps the file open, writes each
new step where the closing tags were and the closing tags after it, in one pwrite,
so a write costs the same however many came before. The frames reach the XML in
batches: every ``flush_every`` writes (and at close) each rank writes its batch, and
the XML of the frames since the last flush is appended once their rows are in the OS
on every rank: on one rank by the worker, in the job of the rows, after them (the
next write waits for that job: it is long done by then); on more, at the next write
(or close) each rank waits for its worker, the ranks meet and rank 0 appends it,
before that write's frame (without the worker: the rows, the ranks meet, the XML, all
in the flush). The batch's depth may differ between ranks (a batch written when
full, between flushes, is the rank's own business); flushes are collective and
counted in writes, the same on every rank. A write changes no HDF5 metadata (a
block's file space is allocated, and its metadata flushed, when the block is made)
and HDF5 keeps no rows (no sieve buffer), so the XML never names data the OS does
not hold, and a run stopped at any point, even killed (the OS keeps what a killed
process wrote), leaves a readable series of the frames of the flushes so far but
those whose XML is still due (a flush's, until the next write); the frames not in
it are lost, at most ``flush_every``, as they always were (when the compiled blocks
write the frames, :meth:`FieldWriter.batch_rows`, a kill in the ~0.1 ms before the
worker has appended a flush's XML loses that flush's frames too). (An H5Fflush per
flush cost ~0.1 ms and added nothing.)
"""
from __future__ import annotations

import os
import re
import sys
from typing import Mapping, Sequence

import numpy as np
from mpi4py import MPI
from numba import njit

from .jit_watch import load
from .errors import OutputError, output_failed
from .worker import Worker, failure, pwrite_all, spare_core

# markers of a frame's XML template (see FieldWriter._template): no XML holds a NUL
_T, _STEP, _ROW = "\x00t\x00", "\x00step\x00", "\x00row\x00"
_MARKERS = re.compile("(\x00(?:t|step|row)\x00)")
_TAIL = b"    </Grid>\n  </Domain>\n</Xdmf>\n"
# XDMF topology of P1 cells by nodes per cell; dolfinx numbers a quadrilateral's vertices
# (0, 0), (1, 0), (0, 1), (1, 1), XDMF (like VTK) goes round the cell: 0, 1, 3, 2
CELL_TYPES = {3: "Triangle", 4: "Quadrilateral"}
QUAD_CYCLE = [0, 1, 3, 2]


def _item(dims: Sequence[int], h5: str, path: str, number: str = "Float", precision: int = 8) -> str:
    d = " ".join(str(int(k)) for k in dims)
    return (f'<DataItem Dimensions="{d}" NumberType="{number}" Precision="{precision}" '
            f'Format="HDF">{h5}:{path}</DataItem>')


def _slab(dims: Sequence[int], h5: str, path: str, start: Sequence[int], count: Sequence[int],
          shape: Sequence[int]) -> str:
    """A float64 DataItem of ``dims`` read from the block ``start`` + ``count`` (unit stride) of
    the dataset ``path`` of shape ``shape``: Xdmf3's heavy-data hyperslab, the content
    'file:/path|start:stride:count:shape'."""
    def j(v):  # (a marker entry stays as it is)
        return " ".join(str(k) for k in v)

    d = j(dims)
    return (f'<DataItem Dimensions="{d}" NumberType="Float" Precision="8" Format="HDF">'
            f'{h5}:{path}|{j(start)}:{j([1] * len(start))}:{j(count)}:{j(shape)}</DataItem>')


@njit(cache=True)
def _point_vectors(u, v, nodes, out) -> None:
    """out[0] = (u_r, u_z, 0) and out[1] = (v_r, v_z, 0) at ``nodes`` (unrolled u, v)."""
    for k in range(nodes.size):
        i = 2 * nodes[k]
        out[0, k, 0] = u[i]
        out[0, k, 1] = u[i + 1]
        out[1, k, 0] = v[i]
        out[1, k, 1] = v[i + 1]


class _Block:
    """One block of frames in a rank's file: ``/frames/points_<b>`` (capacity, 2, nodes, 3)
    and ``/frames/cells_<b>`` (capacity, fields, cells), float64, contiguous, allocated at
    creation; filled with zeros then if ``fill`` (else never: rows not yet written are
    never named by the XML)."""

    def __init__(self, h5, b: int, capacity: int, n_nodes: int, n_fields: int, n_cells: int,
                 fill: bool = False):
        import h5py

        dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
        dcpl.set_fill_time(h5py.h5d.FILL_TIME_ALLOC if fill else h5py.h5d.FILL_TIME_NEVER)
        # the file space now, so a write changes no metadata (see FieldWriter.flush)
        dcpl.set_alloc_time(h5py.h5d.ALLOC_TIME_EARLY)
        dcpl.set_obj_track_times(False)
        self.capacity = capacity
        self.points_path, self.cells_path = f"/frames/points_{b}", f"/frames/cells_{b}"
        self.points_shape = (capacity, 2, n_nodes, 3)
        self.cells_shape = (capacity, n_fields, n_cells)
        self.points = h5py.h5d.create(h5.id, self.points_path.encode(), h5py.h5t.NATIVE_DOUBLE,
                                      h5py.h5s.create_simple(self.points_shape), dcpl=dcpl)
        self.points_space = self.points.get_space()
        self.cells = None
        if n_fields:
            self.cells = h5py.h5d.create(h5.id, self.cells_path.encode(), h5py.h5t.NATIVE_DOUBLE,
                                         h5py.h5s.create_simple(self.cells_shape), dcpl=dcpl)
            self.cells_space = self.cells.get_space()
        # where each dataset's rows start in the file (bytes; contiguous, allocated now), for
        # writing them with os.pwrite: None if HDF5 gives no offset (then h5py writes them)
        self.points_offset = self.points.get_offset()
        self.cells_offset = None if self.cells is None else self.cells.get_offset()
        self.direct = self.points_offset is not None and (
            self.cells is None or self.cells_offset is not None)


def _write_ranges(job: list) -> None:
    """A worker's job: each (file descriptor, bytes, offset) of ``job`` written, in order."""
    for fd, data, offset in job:
        pwrite_all(fd, data, offset)


class FieldWriter:
    """XDMF + HDF5 fields of a :class:`~impact_fenics.bodies.DeformableModel`.

    ``cell_fields``: names of the cell fields handed to every :meth:`write` (besides
    the five stresses, e.g. a plastic strain); ``static_cell_fields``: cell fields
    written once (``body_id`` is always one: the index of the cell's body in the
    model's order). Cell arrays are over this rank's owned cells, in local order.
    ``n_frames``: how many writes the run will make, if known (the first block of frames
    is made that long at set-up, or as long as ``FILL_LIMIT`` bytes allow; more writes,
    or an unknown count, add blocks of frames as they go, each as long as all before
    it, at least ``BLOCK``). ``flush_every``: writes between flushes into the XML; the
    frames are held in a batch of :attr:`depth` frames (``flush_every``, fewer if they would
    pass ``BATCH_LIMIT`` bytes) and reach the file when it is full or at a flush."""

    BLOCK = 16
    FILL_LIMIT = 64 * 2**20  # bytes of the first block (written with zeros at set-up)
    BATCH_LIMIT = 2**20  # bytes a rank's batch of frames may hold (see the module's Batches)
    # batches go to the file on a worker thread where they can (see Batches): where a core
    # is free for it (None: worker.spare_core), always (True) or never (False)
    ASYNC: bool | None = None

    def __init__(self, path: str, model, cell_fields: Sequence[str] = (),
                 static_cell_fields: Mapping[str, np.ndarray] | None = None,
                 flush_every: int = 8, n_frames: int | None = None):
        import h5py

        self.comm: MPI.Comm = model.comm
        comm = self.comm
        self.path = path
        self.cell_fields = list(cell_fields)
        # the names in the file: plane strain names the slots x, out, y (model.geometry;
        # a model without one, the finite-strain driver's, is axisymmetric)
        geometry = getattr(model, "geometry", None)
        self._public = geometry.public if geometry is not None else str
        mesh = model.mesh
        n_cells = mesh.topology.index_map(2).size_local
        from .compat import cell_dofs  # (the reader below must not load dolfinx)

        cell_nodes = cell_dofs(model.V)[:n_cells]
        if cell_nodes.shape[1] == 4:  # a quadrilateral: dolfinx's tensor order -> XDMF's cycle
            cell_nodes = cell_nodes[:, QUAD_CYCLE]
        self._cell_type = CELL_TYPES[cell_nodes.shape[1]]
        # the piece: owned cells and their nodes, nodes in order of their local index
        self._nodes = np.unique(cell_nodes.ravel()).astype(np.int64)
        renumber = np.full(model.node_xy.shape[0], -1, dtype=np.int64)
        renumber[self._nodes] = np.arange(self._nodes.size)
        topology = renumber[cell_nodes]
        self.n_cells, self.n_nodes = n_cells, self._nodes.size
        self._scatter = None
        if comm.size > 1:
            from dolfinx import fem

            self._scatter = (fem.Function(model.V), fem.Function(model.V))
        body_id = np.zeros(n_cells, dtype=np.int32)
        for k, name in enumerate(model.bodies):
            cells = model.tmesh.cells(name)
            body_id[cells[cells < n_cells]] = k
        static = {"body_id": body_id, **dict(static_cell_fields or {})}
        name = "fields.h5" if comm.size == 1 else f"fields_p{comm.rank}.h5"
        self._h5_name = os.path.basename(os.path.splitext(path)[0]) + name[len("fields"):]
        h5_path = os.path.join(os.path.dirname(os.path.abspath(path)), self._h5_name)
        # no sieve buffer: rows go to the OS (pwrite) in the HDF5 call that writes them
        fapl = h5py.h5p.create(h5py.h5p.FILE_ACCESS)
        fapl.set_sieve_buf_size(0)
        self._h5 = h5py.File(h5py.h5f.create(h5_path.encode(), h5py.h5f.ACC_TRUNC, fapl=fapl))
        self._h5.create_dataset("/mesh/geometry", data=model.node_xy[self._nodes])
        self._h5.create_dataset("/mesh/topology", data=topology)
        for key, values in static.items():
            self._h5.create_dataset(f"/mesh/{key}", data=np.asarray(values)[:n_cells])
        self._h5.create_group("/frames")
        self._h5.flush()
        self._static = {k: np.asarray(v).dtype for k, v in static.items()}
        self.flush_every = max(1, int(flush_every))
        n_fields = len(self.cell_fields)
        frame_bytes = 8 * (6 * self.n_nodes + n_fields * n_cells)
        self.depth = max(1, min(self.flush_every, self.BATCH_LIMIT // max(frame_bytes, 1)))
        self._held = 0  # frames in the batch (the last ones of the pending frames)
        self._blocks: list[_Block] = []
        # per block, the XML of a frame (rank 0): its text split at the markers, and where
        # each marker was (see _step_xml)
        self._templates: list[tuple[list[str], list[int], list[int], list[int]]] = []
        self._row = 0  # the next row of the last block
        # every rank's piece sizes and file, for the XML on rank 0
        self._pieces = comm.gather((self.n_nodes, self.n_cells, self._h5_name), root=0)
        self._xml = None
        self._tail_at = 0
        self.n_writes = 0
        # the frames not yet in the XML: time (s), step, block and row; ``_due``: they are
        # all flushed (their batch handed to the worker), the XML is due at the next write
        self._n_pending = 0
        self._due = False
        self._times = np.zeros(self.flush_every)
        self._where = np.zeros((self.flush_every, 3), dtype=np.int64)  # step, block, row
        if comm.rank == 0:
            self._xml = open(path, "wb")  # (appended with os.pwrite at _tail_at, see _xml_job)
            names = ", ".join(f"{k}: {n}" for k, n in enumerate(model.bodies))
            plane = ("" if geometry is None or not geometry.plane else
                     f'    <Information Name="geometry" Value="plane_strain, thickness '
                     f'{geometry.thickness!r} m"/>\n')
            head = ('<?xml version="1.0"?>\n<Xdmf Version="3.0" xmlns:xi="http://www.w3.org/2001/XInclude">\n'
                    '  <Domain>\n'
                    f'    <Information Name="body_id" Value="{names}"/>\n' + plane +
                    '    <Grid Name="fields" GridType="Collection" CollectionType="Temporal">\n')
            self._xml.write(head.encode())
            self._tail_at = self._xml.tell()
            self._xml.write(_TAIL)
            self._xml.flush()
        # the run's known frames, as many as FILL_LIMIT holds, written with zeros now, at
        # set-up (a long run's gigabytes of zeros would cost the set-up more, and a run
        # stopped early would leave a file sized for frames it never wrote)
        self._n_frames = max(1, int(n_frames)) if n_frames else None
        if self._n_frames:
            self._add_block(max(1, min(self._n_frames, self.FILL_LIMIT // max(frame_bytes, 1))),
                            fill=True)
        else:
            self._add_block(self.BLOCK)
        # the worker thread and its descriptor of this rank's file (beside HDF5's), when the
        # rows can go there as raw bytes: the file is the POSIX one (sec2 driver: an offset
        # is a byte of the file), HDF5 gives the datasets' offsets and the machine's
        # float64 is H5T_NATIVE_DOUBLE's little-endian IEEE (the bytes in memory are the
        # bytes in the file); else h5py writes every batch on this thread
        self._worker: Worker | None = None
        self._fd = -1
        self._failed = False
        threaded = spare_core(comm) if self.ASYNC is None else self.ASYNC
        if (threaded and sys.byteorder == "little" and self._blocks[0].direct
                and self._h5.id.get_access_plist().get_driver() == h5py.h5fd.SEC2):
            self._fd = os.open(h5_path, os.O_WRONLY)
            self._worker = Worker(f"fields-p{comm.rank}")
        # do the batches go to the file on the worker thread (else h5py writes them here)?
        self.asynchronous = self._worker is not None
        # the batch: the frames written but not yet in the file, ``depth`` deep (see
        # BATCH_LIMIT), their point vectors (component 2 stays 0) and cell fields, twice
        # with the worker (one is filled while the other is written); a caller computes a
        # frame's cell fields into the staging row (cell_values, cell_block), copied into
        # the batch by write (without the worker, at depth 1 the staging row is the batch's
        # row; with it, the staging row is free when write returns, the batch's row is not)
        self._batches = [(np.zeros((self.depth, 2, self.n_nodes, 3)),
                          np.zeros((self.depth, n_fields, n_cells)))
                         for _ in range(1 if self._worker is None else 2)]
        for batch in self._batches:  # their pages touched now, not at a frame's first write
            for a in batch:
                a.fill(0.0)
        self._bytes = [tuple(memoryview(a.reshape(-1).view(np.uint8)) for a in batch)
                       for batch in self._batches]
        self._rows_of = [(list(p), list(c)) for p, c in self._batches]
        self._current = 0  # the batch being filled; the worker's job of each batch
        self._batch_job = [0] * len(self._batches)
        self._flush_job = 0  # the worker's job that holds the last flush's XML (one rank)
        self._batch_points, self._batch_cells = self._batches[0]
        self._point_rows, self._cell_rows = self._rows_of[0]
        self._cells = (self._cell_rows[0] if self.depth == 1 and self._worker is None
                       else np.zeros((n_fields, n_cells)))
        self.cell_values = {key: self._cells[k] for k, key in enumerate(self.cell_fields)}
        self._rows = list(self.cell_values.values())
        self._points_memory = h5py.h5s.create_simple(self._batch_points.shape)
        self._cells_memory = h5py.h5s.create_simple(self._batch_cells.shape)
        self._point_bytes, self._cell_bytes = 48 * self.n_nodes, 8 * n_fields * n_cells  # a row
        load(_point_vectors, np.zeros(2), np.zeros(2), self._nodes, self._point_rows[0])

    # ------------------------------------------------------------ writing
    def ghosted(self, owned: np.ndarray, k: int = 0) -> np.ndarray:
        """Unrolled values of every local node (ghosts updated by a scatter) from the owned
        ones, in buffer ``k`` (0 or 1: two fields at once); the owned array itself on one rank."""
        if self._scatter is None:
            return owned
        fn = self._scatter[k]
        fn.x.array[: owned.size] = owned
        fn.x.scatter_forward()
        return fn.x.array

    def cell_block(self, names: Sequence[str]) -> np.ndarray:
        """The rows of :attr:`cell_values` of ``names`` (consecutive in ``cell_fields``) as one
        (len(names), n_cells) array, to compute a frame's cell fields in place."""
        i = self.cell_fields.index(names[0])
        if self.cell_fields[i: i + len(names)] != list(names):
            raise ValueError(f"{list(names)} are not consecutive cell fields of the writer")
        return self._cells[i: i + len(names)]

    def _add_block(self, capacity: int, fill: bool = False) -> None:
        """A new block of ``capacity`` frames (and, on rank 0, the XML template of its frames),
        written with zeros if ``fill``."""
        self._blocks.append(_Block(self._h5, len(self._blocks), capacity, self.n_nodes,
                                   len(self.cell_fields), self.n_cells, fill))
        self._h5.flush()  # the block's metadata (its datasets, their file space) on disk
        if self._xml is not None:
            parts = _MARKERS.split(self._template(len(self._blocks) - 1))
            self._templates.append((parts, *([i for i, p in enumerate(parts) if p == m]
                                             for m in (_T, _STEP, _ROW))))
        self._row = 0

    def _slot(self) -> tuple[int, int]:
        """(block, row) of the next frame, adding a block when the last one is full."""
        if self._row == self._blocks[-1].capacity:
            held = sum(b.capacity for b in self._blocks)
            capacity = max(held, self.BLOCK)  # as long as all before it: the file at most
            if self._n_frames and self._n_frames > held:  # doubles what was written
                capacity = min(capacity, self._n_frames - held)
            self._add_block(capacity)
        self._row += 1
        return len(self._blocks) - 1, self._row - 1

    def write(self, t: float, step: int, u: np.ndarray, v: np.ndarray,
              cell_values: Mapping[str, np.ndarray]) -> None:
        """Take the fields at time t (s) of step ``step`` into the batch: u (m) and v (m/s)
        unrolled over the local nodes (see :meth:`ghosted`), and an array over the owned
        cells for every name of ``cell_fields`` (e.g. the arrays of :attr:`cell_values`,
        filled in place: they are free for the next frame when write returns). The batch
        goes to the file when full, and into the XML every ``flush_every`` writes (with
        the worker thread on more ranks, at the write after: see the module's XML).
        Raises OSError if the worker failed to write a batch (disk full, I/O error)."""
        i = self._ready()
        cells = self._cell_rows[i]
        if cell_values is self.cell_values:
            if cells is not self._cells:
                cells[:] = self._cells
        else:
            missing = [k for k in self.cell_fields if k not in cell_values]
            if missing:
                raise ValueError(f"cell fields {missing} missing: every write holds every field")
            for j, key in enumerate(self.cell_fields):
                values = cell_values[key]
                if values is not self._rows[j] or cells is not self._cells:
                    cells[j] = values[: self.n_cells]
        _point_vectors(u, v, self._nodes, self._point_rows[i])
        self.written(t, step)

    def _ready(self, flushed: bool = True) -> int:
        """The batch's next row (the frames it holds), free to fill: the last flush
        published, and with the worker its news taken, for an empty batch its last job
        done and, if ``flushed``, the last flush's job done (its XML written: a run killed
        from here loses the frames since only)."""
        if self._due:  # the frames of the last flush: in the OS (waited for), then the XML
            self._publish()
        i = self._held
        if self._worker is not None:
            job = 0 if i else self._batch_job[self._current]
            self._take(max(job, self._flush_job) if flushed else job)
        return i

    def batch_rows(self) -> tuple[np.ndarray, np.ndarray, int, int]:
        """(point vectors, cell fields, first row, end row) of the batch: rows first ..
        end - 1 are free to fill, the frames before the batch goes to the file (full, or
        a flush due). For a caller that fills them itself (point rows as
        :func:`_point_vectors` does, cell rows in ``cell_fields`` order), then calls
        :meth:`written` for each, in order, before any other write or batch_rows. (Unlike
        :meth:`write`, it does not wait for the last flush's job: the caller fills rows
        while the worker writes. A run killed before that job is done, about 0.1 ms on a
        small mesh, loses that flush's frames too.)"""
        i = self._ready(flushed=False)
        end = i + min(self.depth - i, self.flush_every - self._n_pending)
        return self._batch_points, self._batch_cells, i, end

    def written(self, t: float, step: int) -> None:
        """The batch's next row now holds the frame at time t (s) of step ``step``: it goes
        to the file when the batch is full, into the XML every ``flush_every`` writes."""
        b, row = self._slot()
        k = self._n_pending
        self._times[k] = t
        self._where[k] = step, b, row
        self._n_pending += 1
        self._held += 1
        self.n_writes += 1
        if self._n_pending >= self.flush_every:
            if self._worker is not None and self.comm.size > 1:
                self._write_batch()
                self._due = True  # the ranks meet at the next write: their rows are written
            else:
                self._write_batch(publish=True)
        elif self._held == self.depth:
            self._write_batch()

    def _write_batch(self, publish: bool = False) -> None:
        """Write the batch's frames into their rows of the file, each run of consecutive rows
        of a block (two runs when the batch straddles a full block and the next) as one
        byte range per dataset: with the worker, its job (os.pwrite of the batch's bytes at
        the rows' offsets; the other batch is filled meanwhile), else one h5py hyperslab
        write per dataset. Local to the rank, unless ``publish`` (collective): then the
        pending frames go into the XML after their rows, in the worker's same job (one
        rank), or after the ranks meet (no worker; see :meth:`_publish` for the worker on
        more ranks)."""
        import h5py

        held, double = self._held, h5py.h5t.NATIVE_DOUBLE
        where = self._where[self._n_pending - held: self._n_pending]
        n_fields = len(self.cell_fields)
        worker, fd, job = self._worker, self._fd, []
        points_bytes, cells_bytes = self._bytes[self._current]
        pb, cb = self._point_bytes, self._cell_bytes
        first = 0
        while first < held:
            b, row = int(where[first, 1]), int(where[first, 2])
            last = first + 1
            while last < held and where[last, 1] == b and where[last, 2] == row + last - first:
                last += 1
            count, block = last - first, self._blocks[b]
            if worker is not None and block.direct:
                job.append((fd, points_bytes[first * pb: last * pb], block.points_offset + row * pb))
                if block.cells is not None:
                    job.append((fd, cells_bytes[first * cb: last * cb],
                                block.cells_offset + row * cb))
                first = last
                continue
            self._points_memory.select_hyperslab((first, 0, 0, 0), (count, 2, self.n_nodes, 3))
            block.points_space.select_hyperslab((row, 0, 0, 0), (count, 2, self.n_nodes, 3))
            block.points.write(self._points_memory, block.points_space, self._batch_points,
                               mtype=double)
            if block.cells is not None:
                self._cells_memory.select_hyperslab((first, 0, 0), (count, n_fields, self.n_cells))
                block.cells_space.select_hyperslab((row, 0, 0), (count, n_fields, self.n_cells))
                block.cells.write(self._cells_memory, block.cells_space, self._batch_cells,
                                  mtype=double)
            first = last
        self._held = 0
        if publish and self._n_pending:
            # no H5Fflush: the rows go to the OS by pwrite (the worker's before the XML's,
            # or HDF5's in the calls above: no sieve buffer) and a write changes no metadata
            # (the blocks' file space was allocated and flushed at their creation), so the
            # OS holds every frame the XML will name, which a killed process does not lose;
            # without the worker the ranks meet so that every piece is there before the XML
            # names it (with it, there is one rank)
            if worker is None:
                self.comm.barrier()
                self._append_xml()
            else:
                job += self._xml_job()
        if worker is not None and held:  # the batch to the worker; fill the other one
            self._batch_job[self._current] = worker.submit(_write_ranges, job)
            self._current = 1 - self._current
            self._batch_points, self._batch_cells = self._batches[self._current]
            self._point_rows, self._cell_rows = self._rows_of[self._current]
        elif job:
            worker.submit(_write_ranges, job)
        if publish and worker is not None:
            self._flush_job = worker.submitted

    def _xml_job(self) -> list:
        """[(descriptor, bytes, offset)] of the XML of the pending frames (rank 0; [] on the
        others): the frames where the closing tags were, the closing tags after them; the
        pending frames are then none (in the XML once these bytes are written)."""
        n = self._n_pending
        self._n_pending = 0
        if self._xml is None or not n:
            return []
        text = "".join(self._step_xml(float(self._times[k]), *self._where[k].tolist())
                       for k in range(n)).encode()
        at = self._tail_at
        self._tail_at += len(text)
        return [(self._xml.fileno(), text + _TAIL, at)]

    def _take(self, job: int | None = None, collective: bool = False) -> None:
        """Wait for the worker's jobs up to number ``job`` (all if None), take the outcomes of
        those done after it, and raise its failure as OSError: on one rank at once, on more
        only when ``collective`` (then every rank raises if one failed, so the ranks stop
        together and none waits for one that stopped)."""
        worker = self._worker
        worker.wait(job)
        worker.wait(block=False)
        failed = worker.error is not None
        if self.comm.size > 1:
            if not collective:
                return
            failed = self.comm.allreduce(failed, op=MPI.LOR)
        if not failed:
            return
        self._failed = True
        exc = worker.error
        if exc is None:
            raise OutputError("writing the fields' frames failed on another rank")
        raise failure(exc, self._h5_name, "the fields' frames") from exc

    def _publish(self) -> None:
        """With the worker on more than one rank: the frames of the last flush into the XML
        (collective), once their rows are in the OS on every rank (each rank's worker
        waited for, then the ranks meet): rank 0 appends them (one pwrite)."""
        self._due = False
        if self._n_pending:
            self._take(collective=True)
            self._append_xml()

    def wait(self) -> None:
        """Wait for this rank's worker thread (local): on return the OS holds every row it
        was given and the XML of every flush so far (on more ranks: but the last one's, due
        at the next write); a failure is raised at the next write, flush or close. Nothing
        to wait for without the worker."""
        if self._worker is not None:
            self._worker.wait()

    def flush(self) -> None:
        """Put the frames written so far into the file and the XML (collective); on return
        they are there (the worker waited for)."""
        if self._worker is not None and self.comm.size > 1:
            self._write_batch()
            self._publish()
        else:
            self._write_batch(publish=True)
        if self._worker is not None:
            self._take(collective=True)

    def _step_xml(self, t: float, step: int, b: int, row: int) -> str:
        """The XML of one frame: its block's template with the time, step and row (put in
        the places of the markers and joined: three str.replace of the bars' 2.3 kB
        template cost 2.6 us a frame)."""
        parts, at_t, at_step, at_row = self._templates[b]
        for places, value in ((at_t, repr(t)), (at_step, str(step)), (at_row, str(row))):
            for i in places:
                parts[i] = value
        return "".join(parts)

    def _template(self, b: int) -> str:
        """The XML of a frame of block ``b``, with the time, step and row left to fill
        (the markers _T, _STEP, _ROW)."""
        block = self._blocks[b]
        npc = 4 if self._cell_type == "Quadrilateral" else 3
        n_fields = len(self.cell_fields)
        lines = [f'      <Grid Name="step_{_STEP}" GridType="Collection" CollectionType="Spatial">',
                 f'        <Time Value="{_T}"/>']
        for p, (n_nodes, n_cells, h5) in enumerate(self._pieces):
            lines += [
                f'        <Grid Name="piece_{p}" GridType="Uniform">',
                f'          <Topology TopologyType="{self._cell_type}" NumberOfElements="{n_cells}" '
                f'NodesPerElement="{npc}">{_item((n_cells, npc), h5, "/mesh/topology", "Int")}'
                '</Topology>',
                f'          <Geometry GeometryType="XY">{_item((n_nodes, 2), h5, "/mesh/geometry")}'
                '</Geometry>']
            for j, key in enumerate(("displacement", "velocity")):
                item = _slab((n_nodes, 3), h5, block.points_path, (_ROW, j, 0, 0),
                             (1, 1, n_nodes, 3), (block.capacity, 2, n_nodes, 3))
                lines.append(f'          <Attribute Name="{key}" AttributeType="Vector" '
                             f'Center="Node">{item}</Attribute>')
            for j, key in enumerate(self.cell_fields):
                item = _slab((n_cells,), h5, block.cells_path, (_ROW, j, 0), (1, 1, n_cells),
                             (block.capacity, n_fields, n_cells))
                lines.append(f'          <Attribute Name="{self._public(key)}" '
                             f'AttributeType="Scalar" Center="Cell">{item}</Attribute>')
            for key, dtype in self._static.items():
                kind = "Int" if np.issubdtype(dtype, np.integer) else "Float"
                lines.append(f'          <Attribute Name="{key}" AttributeType="Scalar" Center="Cell">'
                             f'{_item((n_cells,), h5, f"/mesh/{key}", kind, dtype.itemsize)}</Attribute>')
            lines.append("        </Grid>")
        lines.append("      </Grid>\n")
        return "\n".join(lines)

    def _append_xml(self) -> None:
        """The pending frames into the XML, on this thread (rank 0; a failed write stops
        every rank: errors.output_failed)."""
        try:
            _write_ranges(self._xml_job())
        except OSError as exc:
            output_failed(failure(exc, os.path.basename(self.path), "the fields' XML"))

    def close(self) -> None:
        """Flush the last frames (collective, unless a write failed: then this rank's files
        are closed as they are) and close the files; the worker thread ends."""
        try:
            if self._h5 is not None and not self._failed:
                self.flush()
        finally:
            if self._worker is not None:
                self._worker.stop()
                self._worker = None
            if self._fd >= 0:
                os.close(self._fd)
                self._fd = -1
            if self._h5 is not None:
                self._blocks.clear()
                self._h5.close()
                self._h5 = None
            if self._xml is not None:
                self._xml.close()
                self._xml = None


# ----------------------------------------------------------------------------- reading back

def data_item(item, xdmf_dir: str) -> np.ndarray:
    """The array of an XDMF DataItem: HDF ('file.h5:/path', or Xdmf3's hyperslab of one,
    'file.h5:/path|start:stride:count:shape'), XML text, or an XDMF HyperSlab item."""
    import h5py

    if item.get("ItemType") == "HyperSlab":
        sel, source = item.findall("DataItem")
        start, stride, count = np.array(sel.text.split(), dtype=np.int64).reshape(3, -1)
        filename, _, dataset = source.text.strip().partition(":")
        index = tuple(slice(a, a + s * c, s) for a, s, c in zip(start, stride, count))
        with h5py.File(os.path.join(xdmf_dir, filename), "r") as f:
            data = f[dataset][index]
    elif item.get("Format") == "HDF":
        source, _, slab = item.text.strip().partition("|")
        filename, _, dataset = source.partition(":")
        index = ...
        if slab:  # Xdmf3's 'file:/path|start:stride:count:shape'
            start, stride, count = (np.array(s.split(), dtype=np.int64)
                                    for s in slab.split(":")[:3])
            index = tuple(slice(a, a + s * c, s) for a, s, c in zip(start, stride, count))
        with h5py.File(os.path.join(xdmf_dir, filename), "r") as f:
            data = f[dataset][index]
    else:
        data = np.array(item.text.split(), dtype=float)
    dims = [int(d) for d in item.get("Dimensions").split()]
    return np.asarray(data).reshape(dims)


class FieldSeries:
    """A fields.xdmf read back: the pieces joined into one mesh (points (n, 2) in m, cells
    (m, 3) triangles or (m, 4) quadrilaterals), the output times (s), each field's centring ("Node" or "Cell") and, by
    :meth:`values`, its values at an output (nodal fields (n, 3), cell fields (m,))."""

    def __init__(self, path: str):
        import xml.etree.ElementTree as ET

        self.path = path
        self.dir = os.path.dirname(os.path.abspath(path))
        root = ET.parse(path).getroot()
        series = root.find("Domain/Grid")
        if series is None or series.get("CollectionType") != "Temporal":
            raise ValueError("no temporal collection of grids")
        self.steps = series.findall("Grid")
        if not self.steps:
            raise ValueError("no output time")
        self.times = np.array([float(s.find("Time").get("Value")) for s in self.steps])
        pieces = self.steps[0].findall("Grid")
        points, cells, offset = [], [], 0
        for piece in pieces:
            xy = data_item(piece.find("Geometry/DataItem"), self.dir)
            points.append(xy[:, :2])
            cells.append(data_item(piece.find("Topology/DataItem"), self.dir).astype(np.int64) + offset)
            offset += xy.shape[0]
        self.points = np.concatenate(points)
        self.cells = np.concatenate(cells)
        self.center = {a.get("Name"): a.get("Center") for a in pieces[0].findall("Attribute")}
        info = root.find("Domain/Information[@Name='geometry']")
        # "axisymmetric" or "plane_strain" (the writer's Information element, if any)
        self.geometry = "axisymmetric" if info is None else info.get("Value").split(",")[0]

    def values(self, name: str, k: int) -> np.ndarray:
        """Field ``name`` at output k, the pieces joined in order."""
        parts = [data_item(piece.find(f"Attribute[@Name='{name}']/DataItem"), self.dir)
                 for piece in self.steps[k].findall("Grid")]
        return np.concatenate(parts)
