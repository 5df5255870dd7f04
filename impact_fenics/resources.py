"""Size, steps, memory, time and disk of a run, from the scene before anything is meshed.

**Cells and dofs.** A generator mesh is counted from its parameters, region by
region (a body's part of the mesh): a structured grid of alternating diagonals
has 2 n_r n_z triangles on (n_r + 1)(n_z + 1) nodes; an unstructured one about
A / (sqrt(3)/4 h^2) triangles (equilateral triangles of side h over the area A,
m^2) on 1 + (F + B) / 2 nodes (Euler's formula for F triangles with B edges on
the boundary, about the perimeter over h); the graded block integrates the
density 1 / (sqrt(3)/4 h^2) of its size field h = min(h_surface + grading d,
h_max), d the distance to the face under the breaks; quadrilaterals n_r n_z on
(n_r + 1)(n_z + 1) nodes. Two dofs a node. A mesh file is counted as read
(meshing.msh_size).

**Steps.** t_end / dt; with cfl, dt = cfl x the element bound, about
DT_FACTOR x h / c1 of each region's element size h and its body's dilatational
speed c1 (the smallest over the regions; calibrated on the shipped scenes).
At finite strain against a wall the cells flatten and the step falls: the
estimate takes FLATTENING times the steps of the undeformed cells (the shipped
Taylor bar's ratio).

**Memory** (peak resident size measured on bar meshes of 4k to 260k dofs):
BASE_BYTES_PER_RANK of libraries and compiled forms a rank, BYTES_PER_DOF
(mesh, gmsh model on rank 0, K and A, vectors), and the in-memory history (8 B
a value, twice for its doubling buffer).

**Time**: set-up (imports, mesh, forms, kernels from the cache) SETUP_SECONDS
plus SETUP_SECONDS_PER_CELL a cell; the steps SECONDS_PER_STEP a step and
SECONDS_PER_DOF_STEP a dof (PLASTIC_... for path-dependent bodies,
FINITE_SECONDS_PER_CELL_STEP a cell at finite strain, the other bodies' dofs beside
them at their rate) shared by the ranks; and,
where numba's cache is cold (a first run), COMPILE_SECONDS times the share of
the kernels that compile. Calibrated on the shipped scenes on a loaded 2-core
machine (`impact-fenics check` against the run's wall time): estimates to
refuse what cannot fit and to say what to expect, not predictions.

**Disk**: fields.h5 (xdmf.py) holds the mesh and, per frame, u and v padded to
three components at every node and each cell field at every cell, 8 B a value
(at finite strain the frames come in blocks that double: the file is the
blocks' size); fields.xdmf about XDMF_BYTES_PER_FRAME a frame and rank; the
CSV tables about CSV_BYTES_PER_VALUE a value (17 significant digits; zeros are
short); contact_pairs.h5 24 B a pair a row; the pictures and the summary.
"""
from __future__ import annotations

import math
import os
import shutil
from dataclasses import dataclass, field
from typing import Any

BASE_BYTES_PER_RANK = 250e6
BYTES_PER_DOF = 1.5e3
EQUILATERAL = math.sqrt(3.0) / 4.0  # area of an equilateral triangle of side 1
# the element bound dt = 2 / omega_max over h / c1 of a region (s per s): triangles of a
# structured grid of alternating diagonals, of an unstructured (frontal Delaunay) mesh,
# square quadrilaterals at finite strain (min A / max diagonal = h / sqrt 2)
DT_FACTOR = {"structured": 0.65, "unstructured": 0.45, "quad": math.sqrt(0.5)}
FLATTENING = 14.0
SETUP_SECONDS = 3.0
SETUP_SECONDS_PER_CELL = 2e-5
SECONDS_PER_STEP = 5e-6
SECONDS_PER_DOF_STEP = 7e-9
PLASTIC_SECONDS_PER_DOF_STEP = 4e-8
FINITE_SECONDS_PER_CELL_STEP = 1.1e-6
COMPILE_SECONDS = 30.0
XDMF_BYTES_PER_FRAME = 2.5e3
CSV_BYTES_PER_VALUE = 16.0
PAIR_BYTES = 24.0
PICTURES_BYTES = 2.5e5  # history.png, energy.png, summary.json and the scene's copy
FIELD_BLOCK = 16  # xdmf.FieldWriter.BLOCK: the first block of frames of unknown count


@dataclass
class Region:
    """A body's part of a generator mesh: its cell group, cells, nodes, its smallest
    element size h (m) and its kind (a key of DT_FACTOR)."""

    body: str
    cells: float
    nodes: float
    h: float
    kind: str


def _rectangle(body: str, width: float, height: float, h: float, structured: bool,
               n_r: int | None = None) -> Region:
    """A rectangle width x height (m) of element size h (m); ``n_r`` intervals on the
    sides along r (default round(width / h))."""
    n_r = n_r or max(1, round(width / h))
    n_z = max(1, round(height / h))
    if structured:
        return Region(body, 2.0 * n_r * n_z, (n_r + 1.0) * (n_z + 1.0), h, "structured")
    cells = width * height / (EQUILATERAL * h * h)
    return Region(body, cells, 1.0 + 0.5 * (cells + 2 * n_r + 2 * n_z), h, "unstructured")


def _graded_block(p: dict) -> Region:
    """punch_block: the integral of 1 / (sqrt(3)/4 h^2) over the block and of 1 / h along
    its boundary, h = min(h_surface + grading d, h_max) with d the distance to the face
    0 <= r <= r_last of the breaks (midpoint sums on grids finer than h / 4)."""
    import numpy as np

    hs, g, h_max = p["h_surface"], p["grading"], p["h_max"]
    width, depth, breaks = p["width"], p["depth"], p["breaks"]
    r_last = breaks[-1][0]

    def size(d):
        return np.minimum(hs + g * d, h_max)

    def grid(a: float, b: float, start: float) -> np.ndarray:
        """Points a = x_0 < ... < x_n = b spaced a quarter of the size at distance
        start + (x - a) from the face."""
        xs = [a]
        while xs[-1] < b:
            xs.append(min(b, xs[-1] + 0.25 * float(size(start + xs[-1] - a))))
        return np.array(xs)

    r = np.concatenate([np.linspace(0.0, r_last, max(2, int(4 * r_last / hs)) + 1),
                        grid(r_last, width, 0.0)[1:]])
    z = grid(0.0, depth, 0.0)
    rm, zm = 0.5 * (r[1:] + r[:-1]), 0.5 * (z[1:] + z[:-1])
    d = np.hypot(np.maximum(rm[:, None] - r_last, 0.0), zm[None, :])
    cells = float(np.sum(np.outer(np.diff(r), np.diff(z)) / (EQUILATERAL * size(d) ** 2)))
    far = np.hypot(width - r_last, zm)  # the side r = width, the bottom, the axis
    bottom = np.hypot(np.maximum(rm - r_last, 0.0), depth)
    edges = (sum(n for _, n in breaks) + np.sum(np.diff(r)[rm > r_last] / size(rm[rm > r_last] - r_last))
             + np.sum(np.diff(z) / size(far)) + np.sum(np.diff(r) / size(bottom))
             + np.sum(np.diff(z) / size(zm)))
    h_min = min([hs] + [(r1 - r0) / n for (r0, (r1, n)) in
                        zip([0.0] + [b[0] for b in breaks[:-1]], breaks)])
    return Region("block", cells, 1.0 + 0.5 * (cells + float(edges)), h_min, "unstructured")


def _cylinder_on_block_regions(p: dict) -> list[Region]:
    """meshing.cylinder_on_block's two bodies: cells = the integral of dA / (EQUILATERAL
    h(d)^2) of its size field (h_contact within contact_zone of the origin, rising
    linearly to h_far over 20 h_far), sampled on a 200 x 200 grid of each body's box."""
    import numpy as np

    R, hc, hf, zone = p["radius"], p["h_contact"], p["h_far"], p["contact_zone"]
    y0, top = p["gap"], p["gap"] + (R if p["quarter"] else 2 * R)
    regions = []
    boxes = [("cylinder", R, y0, top)] + ([("block", p["block_width"], -p["block_depth"], 0.0)]
                                          if p["block"] else [])
    for name, x1, y_lo, y_hi in boxes:
        x, y = np.meshgrid((np.arange(200) + 0.5) / 200 * x1,
                           y_lo + (np.arange(200) + 0.5) / 200 * (y_hi - y_lo))
        inside = (np.hypot(x, y - y0 - R) <= R) if name == "cylinder" else np.ones_like(x, bool)
        d = np.hypot(x, y - y0 if name == "cylinder" else y)  # to the nearer contact point
        h = np.clip(hc + (hf - hc) * (d - zone) / (20 * hf), hc, hf)
        cells = float((inside / h ** 2).sum()) * x1 * (y_hi - y_lo) / 200 ** 2 / EQUILATERAL
        regions.append(Region(name, cells, 1.0 + 0.5 * cells + 2 * math.sqrt(cells), hc,
                              "unstructured"))
    return regions


def generator_regions(generator: str, p: dict) -> list[Region]:
    """The regions of a generator mesh with parameters ``p`` (its defaults filled in); with
    ``quadrilaterals``, each structured grid's triangle pairs are one quadrilateral."""
    regions = _regions(generator, p)
    if p.get("quadrilaterals") and generator != "block":
        regions = [Region(r.body, 0.5 * r.cells, r.nodes, r.h, "quad") for r in regions]
    return regions


def _regions(generator: str, p: dict) -> list[Region]:
    if generator == "bar":
        return [_rectangle("bar", p["radius"], p["length"], p["h"], p["structured"])]
    if generator in ("coaxial_bars", "coaxial_bars_sized"):
        h = ((p["h"], p["h"]) if generator == "coaxial_bars"
             else (p["h_striker"], p["h_target"]))
        return [_rectangle(body, p["radius"], length, hb, p["structured"])
                for body, length, hb in zip(("striker", "target"),
                                            (p["striker_length"], p["target_length"]), h)]
    if generator == "nosed_striker_on_block":  # a quarter-disc nose and its shank; the block
        a, shank, hs = p["nose_radius"], p["shank_length"], p["h_striker"]
        cells = (0.25 * math.pi * a * a + a * shank) / (EQUILATERAL * hs * hs)
        edges = (0.5 * math.pi * a + shank + a + a + shank) / hs
        striker = Region("striker", cells, 1.0 + 0.5 * (cells + edges), hs, "unstructured")
        return [striker, _rectangle("block", p["block_width"], p["block_depth"], p["h_block"],
                                    False)]
    if generator == "quad_bar":  # n_r x round(n_r length / radius) square quadrilaterals
        n_r = p["n_r"]
        n_z = max(1, round(n_r * p["length"] / p["radius"]))
        return [Region("", float(n_r * n_z), (n_r + 1.0) * (n_z + 1.0), p["radius"] / n_r, "quad")]
    if generator == "rod_on_anvil":  # the rod as quad_bar's; the anvil in squares of its h
        n_r, h = p["n_r"], p["radius"] / p["n_r"]
        n_z = max(1, round(n_r * p["length"] / p["radius"]))
        m_r = max(1, round((p.get("anvil_radius") or 3.0 * p["radius"]) / h))
        m_z = max(1, round((p.get("anvil_depth") or 2.0 * p["radius"]) / h))
        return [Region("rod", float(n_r * n_z), (n_r + 1.0) * (n_z + 1.0), h, "quad"),
                Region("anvil", float(m_r * m_z), (m_r + 1.0) * (m_z + 1.0), h, "quad")]
    if generator == "punch_block":
        return [_graded_block(p)]
    if generator == "shpb":
        bar, spec = 0.5 * p["bar_diameter"], 0.5 * p["specimen_diameter"]
        return [_rectangle("striker", bar, p["striker_length"], p["h_bar"], p["structured"]),
                _rectangle("incident", bar, p["incident_length"], p["h_bar"], p["structured"]),
                _rectangle("specimen", spec, p["specimen_length"], p["h_specimen"],
                           p["structured"]),
                _rectangle("transmitter", bar, p["transmitter_length"], p["h_bar"],
                           p["structured"])]
    if generator == "block":  # a structured grid: triangles, or quadrilaterals
        region = _rectangle("block", p["width"], p["height"], p["h"], True)
        if p["quadrilaterals"]:
            region = Region("block", 0.5 * region.cells, region.nodes, p["h"], "quad")
        return [region]
    if generator == "wedge_on_block":  # the half wedge (a trapezoid with a round tip), the block
        from .meshing import wedge_half_width

        half = wedge_half_width(p["wedge_angle"], p["tip_radius"], p["wedge_height"])
        sides = (2 * p["wedge_height"] + half + math.hypot(half, p["wedge_height"])) / p["h_wedge"]
        cells = 0.5 * half * p["wedge_height"] / (EQUILATERAL * p["h_wedge"] ** 2)
        wedge = Region("wedge", cells, 1.0 + 0.5 * (cells + sides), p["h_wedge"], "unstructured")
        return [wedge, _rectangle("block", p["block_width"], p["block_depth"], p["h_block"],
                                  False)]
    if generator == "striker_on_plate":
        return [_rectangle("striker", p["striker_half_width"], p["striker_length"],
                           p["h_striker"], False),
                _rectangle("plate", p["plate_half_span"], p["plate_thickness"], p["h_plate"],
                           False)]
    if generator == "cylinder_on_block":  # graded from the contact point: a sampled integral
        return _cylinder_on_block_regions(p)
    raise ValueError(generator)


def generator_size(generator: str, p: dict) -> float:
    """The largest extent (m) in r or z of a generator mesh with parameters ``p``."""
    if generator in ("bar", "quad_bar"):
        return max(p["radius"], p["length"])
    if generator == "rod_on_anvil":
        return max(p.get("anvil_radius") or 3.0 * p["radius"],
                   p["length"] + (p.get("anvil_depth") or 2.0 * p["radius"]))
    if generator == "block":
        return max(p["width"], p["height"])
    if generator in ("coaxial_bars", "coaxial_bars_sized"):
        return max(p["radius"], p["striker_length"] + p["target_length"])
    if generator == "nosed_striker_on_block":
        return max(p["block_width"], p["block_depth"] + p["nose_radius"] + p["shank_length"])
    if generator == "punch_block":
        return max(p["width"], p["depth"])
    if generator == "wedge_on_block":
        return max(p["block_width"], p["block_depth"] + p["wedge_height"])
    if generator == "striker_on_plate":
        return max(p["plate_half_span"], p["plate_thickness"] + p["gap"] + p["striker_length"])
    if generator == "cylinder_on_block":
        return max(p["block_width"], p["block_depth"] + p["gap"] + 2 * p["radius"])
    if generator == "shpb":
        return (p["striker_length"] + p["incident_length"] + p["specimen_length"]
                + p["transmitter_length"])
    raise ValueError(generator)


def contact_radius(generator: str | None, p: dict) -> float | None:
    """The radius (m) of the contact faces of a generator mesh (None: not known)."""
    if generator in ("bar", "quad_bar", "coaxial_bars", "coaxial_bars_sized", "rod_on_anvil"):
        return p["radius"]
    if generator == "nosed_striker_on_block":
        return p["nose_radius"]
    if generator == "shpb":
        return 0.5 * p["bar_diameter"]
    return None


@dataclass
class Estimate:
    cells: float
    dofs: float
    n_steps: float
    memory: float        # bytes, all ranks
    setup: float         # s, wall: imports, mesh, forms, kernels from their cache
    steps_time: float    # s, wall
    compile: float       # s, wall: the kernels whose cache is cold (0: none)
    disk: float          # bytes, every file of the run
    fields: float        # bytes of the field files (fields.h5 or fields_p*.h5)
    frames: float
    flattening: bool = False  # finite strain against a wall: steps x FLATTENING
    parts: dict = field(default_factory=dict)  # bytes by file

    @property
    def time(self) -> float:
        """The run's wall time (s), compile included."""
        return self.setup + self.steps_time + self.compile

    def lines(self, available: float | None, free: float | None) -> list[str]:
        """What the run is estimated to take, on two lines (rank 0 prints them)."""
        avail = f" of {available / 1e9:.3g} GB available" if available else ""
        steps = f"{self.n_steps:,.0f} step{'' if self.n_steps == 1 else 's'}"
        if self.flattening:
            steps += (f" (the step falls as the cells flatten: {FLATTENING:g} x the steps of "
                      "the undeformed cells, as on the shipped Taylor bar)")
        parts = f"set-up {_duration(self.setup)}, steps {_duration(self.steps_time)}"
        if self.compile:
            parts += f", compiling {_duration(self.compile)}"
        fields = (f" (fields {size_text(self.fields)}: {self.frames:,.0f} frames)"
                  if self.fields else "")
        space = f" of {size_text(free)} free" if free is not None else ""
        return [f"estimate: {self.cells:,.0f} cells, {self.dofs:,.0f} dofs, {steps}, about "
                f"{_duration(self.time)} ({parts})",
                f"          {self.memory / 1e9:.3g} GB of memory{avail}, "
                f"{size_text(self.disk)} of output{fields}{space} (rough)"]


def _duration(seconds: float) -> str:
    for unit, size in (("days", 86400.0), ("h", 3600.0), ("min", 60.0)):
        if seconds >= 2 * size:
            return f"{seconds / size:.3g} {unit}"
    return f"{seconds:.2g} s"


def size_text(n: float) -> str:
    """A number of bytes as kB, MB, GB or TB (decimal)."""
    for unit, size in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{n:.0f} B"


@dataclass
class RunShape:
    """What the estimate needs of a scene, in numbers: see :func:`estimate`."""

    cells: float
    nodes: float
    n_steps: float
    n_ranks: int
    finite: bool = False
    finite_cells: float = 0.0     # the cells of the finite-strain bodies (finite: all if 0)
    plastic: bool = False
    flattening: bool = False
    history_columns: int = 2
    history_every: int = 1
    energy_columns: int = 0       # small strain: the energy table's columns
    energy_every: int = 1
    output_every: int = 50
    fields: bool = True
    cell_fields: int = 5
    pairs: list = field(default_factory=list)  # per contact set: pairs
    pairs_every: int = 10
    plots: bool = True
    cold: float = 0.0             # the share of the run's kernels whose cache is cold


def estimate(s: RunShape) -> Estimate:
    """Memory (bytes), time (s) and disk (bytes) of a run of the shape ``s``."""
    dofs = 2.0 * s.nodes
    n = s.n_steps
    history_rows = n / s.history_every + 2  # (an energy row's step has a history row too)
    if s.history_every > 1 and not s.finite:
        history_rows += n / s.energy_every
    memory = (s.n_ranks * BASE_BYTES_PER_RANK + BYTES_PER_DOF * dofs
              + 2 * 8.0 * history_rows * s.history_columns)
    setup = SETUP_SECONDS + SETUP_SECONDS_PER_CELL * s.cells
    per_dof = PLASTIC_SECONDS_PER_DOF_STEP if s.plastic else SECONDS_PER_DOF_STEP
    if s.finite:  # the finite-strain cells, and the small-strain bodies' dofs beside them
        finite_cells = s.finite_cells if 0.0 < s.finite_cells < s.cells else s.cells
        rest = dofs * (1.0 - finite_cells / s.cells)
        steps = n * FINITE_SECONDS_PER_CELL_STEP * finite_cells / s.n_ranks
        if rest > 0.0:
            steps += n * (SECONDS_PER_STEP + per_dof * rest / s.n_ranks)
    else:
        steps = n * (SECONDS_PER_STEP + per_dof * dofs / s.n_ranks)
    parts = {"history.csv": CSV_BYTES_PER_VALUE * history_rows * s.history_columns}
    frames = 0.0
    if s.fields:
        frames = 1.0 + math.ceil(n / s.output_every)
        held = frames
        if s.finite:  # blocks of FIELD_BLOCK frames, each as long as all before it
            held = float(FIELD_BLOCK)
            while held < frames:
                held *= 2.0
        frame = 8.0 * (6.0 * s.nodes + s.cell_fields * s.cells)
        mesh = 8.0 * (2.0 * s.nodes + 3.0 * s.cells) + 4.0 * s.cells
        parts["fields.h5"] = held * frame + mesh
        parts["fields.xdmf"] = XDMF_BYTES_PER_FRAME * frames * s.n_ranks
    if not s.finite:
        parts["energy.csv"] = (CSV_BYTES_PER_VALUE * (n / s.energy_every + 2)
                               * s.energy_columns)
        for k, pairs in enumerate(s.pairs):
            parts[f"contact_pairs{k}.h5"] = PAIR_BYTES * pairs * (n / s.pairs_every + 2)
    parts["pictures and summary"] = PICTURES_BYTES if s.plots else 1e4
    return Estimate(s.cells, dofs, n, memory, setup, steps, COMPILE_SECONDS * s.cold,
                    sum(parts.values()), parts.get("fields.h5", 0.0), frames, s.flattening,
                    parts)


def available_memory() -> float | None:
    """Memory this machine can give now (bytes; MemAvailable of /proc/meminfo)."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024.0
    except OSError:
        pass
    try:
        return float(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError):
        return None


def free_disk(path: str) -> tuple[str, float] | None:
    """(the existing folder that will hold ``path``, its free bytes), or None if unknown."""
    here = os.path.abspath(os.path.expanduser(path))
    while True:
        parent = os.path.dirname(here)
        if os.path.isdir(parent) or parent == here:
            break
        here = parent
    try:
        return parent, float(shutil.disk_usage(parent).free)
    except OSError:
        return None


def generator_params(scene) -> dict[str, Any]:
    """The parameters of the scene's generator mesh, its defaults filled in."""
    import inspect

    from . import meshing

    quad = scene.mesh.generator in ("quad_bar", "rod_on_anvil")  # their keys given or derived
    params = {} if quad else {
        k: v.default for k, v in
        inspect.signature(getattr(meshing, scene.mesh.generator)).parameters.items()
        if v.default is not inspect.Parameter.empty}
    params.update(scene.mesh.params)
    return params
