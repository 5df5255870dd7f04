"""Rough size, memory and time of a run, from the mesh request before anything is meshed.

Cells of a generator mesh follow from its parameters: a structured grid of
alternating diagonals has 2 n_r n_z triangles; an unstructured one about
A / (sqrt(3)/4 h^2) (equilateral triangles of side h over the area A, m^2); the
graded punch block integrates that density over the depth with h(d) =
min(h_surface + grading d, h_max). Dofs: two per node, about one node per two
cells. Memory: measured on this package (bar meshes of 4k to 260k dofs, peak
resident size): about 250 MB of libraries and compiled forms per rank plus
about 1.1 kB per dof (mesh, gmsh model on rank 0, K and A, vectors), taken as
1.5 kB; plus the in-memory history (8 B per value, twice for its doubling
buffer). Time: about 15 ns per dof and step on one core of the development
machine (loaded), shared by the ranks. These are estimates to refuse a request
that cannot fit, not predictions.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass

BASE_BYTES_PER_RANK = 250e6
BYTES_PER_DOF = 1.5e3
SECONDS_PER_DOF_STEP = 15e-9
EQUILATERAL = math.sqrt(3.0) / 4.0  # area of an equilateral triangle of side 1


@dataclass
class Estimate:
    cells: float
    dofs: float
    memory: float     # bytes, all ranks
    time: float       # s, wall
    n_steps: float

    def line(self, available: float | None) -> str:
        avail = f" of {available / 1e9:.3g} GB available" if available else ""
        return (f"estimate: {self.cells:,.0f} cells, {self.dofs:,.0f} dofs, "
                f"{self.memory / 1e9:.3g} GB of memory{avail}, about "
                f"{_duration(self.time)} for {self.n_steps:,.0f} steps (rough)")


def _duration(seconds: float) -> str:
    for unit, size in (("days", 86400.0), ("h", 3600.0), ("min", 60.0)):
        if seconds >= 2 * size:
            return f"{seconds / size:.3g} {unit}"
    return f"{seconds:.2g} s"


def _rect_cells(width: float, height: float, h: float, structured: bool) -> float:
    if structured:
        return 2.0 * max(1, round(width / h)) * max(1, round(height / h))
    return width * height / (EQUILATERAL * h * h)


def generator_cells(generator: str, p: dict) -> tuple[float, float]:
    """(cells, smallest element size in m) of a generator mesh with parameters ``p``
    (the generator's defaults filled in)."""
    if generator == "bar":
        return _rect_cells(p["radius"], p["length"], p["h"], p["structured"]), p["h"]
    if generator == "coaxial_bars":
        cells = sum(_rect_cells(p["radius"], length, p["h"], p["structured"])
                    for length in (p["striker_length"], p["target_length"]))
        return cells, p["h"]
    if generator == "coaxial_bars_sized":
        cells = (_rect_cells(p["radius"], p["striker_length"], p["h_striker"], p["structured"])
                 + _rect_cells(p["radius"], p["target_length"], p["h_target"], p["structured"]))
        return cells, min(p["h_striker"], p["h_target"])
    if generator == "nosed_striker_on_block":  # a quarter-disc nose and its shank; the block
        a = p["nose_radius"]
        striker = (0.25 * math.pi * a * a + a * p["shank_length"]) / (EQUILATERAL * p["h_striker"] ** 2)
        block = p["block_width"] * p["block_depth"] / (EQUILATERAL * p["h_block"] ** 2)
        return striker + block, min(p["h_striker"], p["h_block"])
    if generator == "quad_bar":  # n_r x round(n_r length / radius) quadrilaterals
        return p["n_r"] * max(1, round(p["n_r"] * p["length"] / p["radius"])), p["radius"] / p["n_r"]
    if generator == "punch_block":
        hs, g, h_max = p["h_surface"], p["grading"], p["h_max"]
        hs = min([hs] + [(r1 - r0) / n for (r0, (r1, n)) in
                         zip([0.0] + [b[0] for b in p["breaks"][:-1]], p["breaks"])])
        depth, width = p["depth"], p["width"]
        d_cap = (h_max - hs) / g if g > 0 else math.inf
        d1 = min(depth, d_cap)
        # integral of 1/h(d)^2 over the depth
        inv = (1.0 / g) * (1.0 / hs - 1.0 / (hs + g * d1)) if g > 0 else d1 / hs ** 2
        inv += max(0.0, depth - d1) / h_max ** 2
        return width * inv / EQUILATERAL, hs
    raise ValueError(generator)


def estimate(cells: float, n_steps: float, n_ranks: int, history_columns: int,
             history_every: int, dofs: float | None = None) -> Estimate:
    """Memory (bytes) and wall time (s) of ``cells`` CST cells (or ``dofs`` dofs of another
    element) run for ``n_steps``."""
    if dofs is None:
        dofs = cells + 4.0 * math.sqrt(cells) + 2.0  # 2 per node, ~cells/2 nodes plus the boundary
    rows = n_steps / history_every + 2
    memory = (n_ranks * BASE_BYTES_PER_RANK + BYTES_PER_DOF * dofs
              + 2 * 8.0 * rows * history_columns)
    time = SECONDS_PER_DOF_STEP * dofs * n_steps / n_ranks
    return Estimate(cells, dofs, memory, time, n_steps)


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
