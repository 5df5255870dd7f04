"""Pictures of a run: history plots (matplotlib) and field renders from the XDMF (pyvista).

* :func:`write_history_plots` writes ``history.png`` (every probe, contact force
  and gap, rigid body motion) and ``energy.png`` (every term of the energy ledger
  that is not zero, plastic work included, their total and the balance error)
  into a run directory; :class:`~impact_fenics.simulation.Simulation` calls it on
  rank 0 at the end of every run with an output directory.
* :func:`render_fields` reads ``fields.xdmf`` and its HDF5 file as dolfinx
  writes them and renders one field on the deformed mesh (displacement scaled
  for visibility) at chosen times, offscreen, as PNG files.

Axes are labelled in the units plotted: time in microseconds, stresses in MPa,
displacements in mm, velocities in m/s, forces in N, energies in J. Neither
function imports dolfinx, so plotting a finished run needs no MPI.
"""
from __future__ import annotations

import os
import sys
import textwrap
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from matplotlib.figure import Figure

# (a plane-strain run names the same slots sigma_xx, sigma_yy, sigma_out, sigma_xy, u_x, u_y)
STRESSES = ("sigma_rr", "sigma_zz", "sigma_tt", "sigma_rz", "von_mises",
            "sigma_xx", "sigma_yy", "sigma_out", "sigma_xy")
DISPLACEMENTS = ("u_r", "u_z", "u_x", "u_y")


# ----------------------------------------------------------------------------- histories

def _run_name(run_dir: str) -> str:
    """The name of a run without a title: its directory's (a staging suffix dropped)."""
    return os.path.basename(os.path.normpath(run_dir)).removesuffix(".partial")


def write_history_plots(run_dir: str, history: dict[str, np.ndarray],
                        energy: dict[str, np.ndarray],
                        probes: list[tuple[str, str]] | None = None,
                        title: str | None = None) -> list[str]:
    """Write history.png and energy.png into ``run_dir``; returns the paths written.

    ``history`` and ``energy`` map column names to arrays (time in s);
    ``probes`` lists (column, quantity) of the probe columns; ``title`` names the run
    (a scene's title; default: the directory's name). A failure to plot never loses a
    run: it is reported in one line on stderr and skipped."""
    try:
        title = title or _run_name(run_dir)
        written = []
        path = os.path.join(run_dir, "history.png")
        if _plot_history(path, history, probes or [], title):
            written.append(path)
        path = os.path.join(run_dir, "energy.png")
        if _plot_energy(path, energy, title):
            written.append(path)
        return written
    except Exception as exc:  # a picture must not cost the results
        print(f"warning: history plots not written: {exc}", file=sys.stderr, flush=True)
        return []


def _finite(y: np.ndarray) -> np.ndarray:
    return np.where(np.isfinite(y), y, np.nan)


# the fixed layout of history.png and energy.png, inches: margins that hold the labels (left: a
# y label of two lines and tick labels of 7 characters, "-120000"; right: half of a last time
# tick label "100000" at the edge; top: the title; bottom: the x tick labels and label); no
# layout engine measures the texts at every save
MARGINS = {"left": 1.15, "right": 0.3, "top": 0.35, "bottom": 0.58}


def _figure(n_rows: int, height: float, gap: float, **gridspec) -> tuple[Figure, np.ndarray]:
    """A figure of 8 in x ``height`` in on the Agg canvas (no pyplot, no window) with
    ``n_rows`` axes over each other sharing x, laid out once: :data:`MARGINS` and ``gap``
    inches between the axes (room for a panel's offset text, e.g. "1e6")."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    width = 8.0
    fig = Figure(figsize=(width, height))
    FigureCanvasAgg(fig)
    m = MARGINS
    mean_axes = (height - m["top"] - m["bottom"] - (n_rows - 1) * gap) / n_rows
    fig.subplots_adjust(left=m["left"] / width, right=1.0 - m["right"] / width,
                        top=1.0 - m["top"] / height, bottom=m["bottom"] / height,
                        hspace=gap / mean_axes)
    return fig, fig.subplots(n_rows, 1, sharex=True, squeeze=False, gridspec_kw=gridspec)[:, 0]


# the probe panels: (quantities, y label, factor to the plotted unit)
PROBE_PANELS = ((STRESSES, "probe stress (MPa)", 1e-6),
                (DISPLACEMENTS, "probe displacement (mm)", 1e3),
                (("eps_p_eq",), "probe eps_p_eq (-)", 1.0),
                (("yielded",), "probe yielded (0 / 1)", 1.0),
                (("strain_gauge",), "gauge strain (-)", 1.0),
                (("section",), "section force (kN)", 1e-3))


def probe_panels(h: dict[str, np.ndarray], probes: list[tuple[str, str]]) -> list:
    """[(y label, [(column, values)])]: every probe column of ``h`` in a panel of its
    quantity's kind (a quantity of no listed kind in a panel of its own)."""
    panels = []
    shown = set()
    for quantities, label, factor in PROBE_PANELS:
        curves = [(n, h[n] * factor) for n, q in probes if q in quantities and n in h]
        shown.update(n for n, _ in curves)
        if curves:
            panels.append((label, curves))
    for n, q in probes:
        if n in h and n not in shown:
            panels.append((f"probe {q}", [(n, h[n])]))
    return panels


def _plot_history(path: str, h: dict[str, np.ndarray], probes: list[tuple[str, str]],
                  title: str) -> bool:
    fig = history_figure(h, probes, title)
    if fig is None:
        return False
    fig.savefig(path, dpi=110)
    return True


def history_figure(h: dict[str, np.ndarray], probes: list[tuple[str, str]],
                   title: str) -> Figure | None:
    """The figure of history.png (None when there is nothing to draw)."""
    if "time" not in h or h["time"].size == 0:
        return None
    t = h["time"] * 1e6
    probe_names = {name for name, _ in probes}
    panels = probe_panels(h, probes)  # (ylabel, [(label, values)])
    force = [(c, h[c]) for c in h if c.endswith("_force")]
    if force:
        panels.append(("contact force (N)", force))
        gaps = [(c, h[c] * 1e3) for c in h if c.endswith("min_gap")]
        panels.append(("smallest gap (mm)", gaps))
    rigid_u = [(c, h[c] * 1e3) for c in h if c.endswith("_u") and c not in probe_names]
    rigid_v = [(c, h[c]) for c in h if c.endswith("_v") and c not in probe_names]
    if rigid_u:
        panels.append(("rigid body displacement (mm)", rigid_u))
        panels.append(("rigid body velocity (m/s)", rigid_v))
    if not panels:
        return None
    fig, axes = _figure(len(panels), 1.0 + 2.2 * len(panels), gap=0.35)
    for ax, (label, curves) in zip(axes, panels):
        for name, y in curves:
            ax.plot(t, _finite(y), lw=1.2, label=name)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        ax.legend(fontsize="small", loc="best")
    axes[-1].set_xlabel("t (µs)")
    axes[0].set_title(f"{title}: histories")
    return fig


# the energy panel's curves: (column, label); a column that is zero at every output is
# left out, except the stored energies and their total
ENERGY_CURVES = (("kinetic", "kinetic"), ("strain", "strain (stored elastic)"),
                 ("plastic_work", "plastic work (dissipated)"),
                 ("total", "total = kinetic + strain + plastic work"),
                 ("external_work", "work of loads"), ("contact_work", "work of contact"),
                 ("activation_loss", "activation losses (in the work of contact)"))
ALWAYS = ("kinetic", "strain", "total")


def energy_curves(e: dict[str, np.ndarray]) -> list[tuple[str, str, np.ndarray]]:
    """The curves of energy.png, [(column, label, values in J)]: the ledger's terms of
    :data:`ENERGY_CURVES` (a term that is zero, or round-off, at every output left out:
    :data:`~.report.ROUND_OFF` of the largest, as in the console's line; the stored
    energies and their total always drawn), then, when work was done on the bodies, the
    initial energy plus that work ("balance"): the total follows it to round-off."""
    from .report import ROUND_OFF

    present = [name for name, _ in ENERGY_CURVES if name in e and e[name].size]
    scale = max((float(np.nanmax(np.abs(e[n]))) for n in present), default=0.0)

    def drawn(name: str) -> bool:
        return name in ALWAYS or float(np.nanmax(np.abs(e[name]))) > ROUND_OFF * scale

    curves = [(name, label, _finite(e[name])) for name, label in ENERGY_CURVES
              if name in present and drawn(name)]
    work = sum(e[k] for k in ("external_work", "contact_work") if k in present and drawn(k))
    if "total" in present and np.any(work != 0.0):
        # the initial energy E_0 (the state before the first step, which the first row
        # follows): from the first row's balance, E_0 = total - error - work of the row
        initial = e["total"][0]
        if "balance_error" in e:
            initial = (initial - e["balance_error"][0]
                       - sum(e[k][0] for k in ("external_work", "contact_work") if k in e))
        curves.append(("balance", "initial + work of loads and contact",
                       _finite(initial + work)))
    return curves


def _plot_energy(path: str, e: dict[str, np.ndarray], title: str) -> bool:
    fig = energy_figure(e, title)
    if fig is None:
        return False
    fig.savefig(path, dpi=110)
    return True


def energy_figure(e: dict[str, np.ndarray], title: str) -> Figure | None:
    """The figure of energy.png: :func:`energy_curves` and the relative balance error
    (None without outputs)."""
    if "time" not in e or e["time"].size == 0:
        return None
    t = e["time"] * 1e6
    fig, (ax, ax_err) = _figure(2, 6.5, gap=0.25, height_ratios=[2, 1])
    marker = "." if t.size < 40 else None
    for name, label, y in energy_curves(e):
        if name == "balance":
            ax.plot(t, y, "k--", lw=0.8, label=label)
        else:
            ax.plot(t, y, lw=1.6 if name == "total" else 1.0, label=label, marker=marker)
    ax.set_ylabel("energy, work (J)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small", loc="best")
    ax.set_title(f"{title}: energy ledger")
    err = np.abs(_finite(e.get("balance_error_rel", np.full(t.size, np.nan))))
    shown = np.where(err > 0, err, np.nan)
    ax_err.semilogy(t, shown, ".-", lw=1.0, color="k")
    ax_err.set_ylabel("|total - initial - work|\n/ largest term")
    ax_err.set_xlabel("t (µs)")
    ax_err.grid(alpha=0.3, which="both")
    if not np.any(np.isfinite(shown)):
        ax_err.text(0.5, 0.5, "balance error 0 at every output step", ha="center",
                    va="center", transform=ax_err.transAxes)
    return fig


# ----------------------------------------------------------------------------- fields

@dataclass
class Series:
    """One field of a fields.xdmf: its centring ("Node" or "Cell") and output times (s)."""

    name: str
    center: str
    times: np.ndarray


class XdmfRun:
    """The mesh and the field series of a fields.xdmf (pieces joined; r = x, z = y, in m;
    :attr:`plane`: a plane-strain run's, its coordinates x and y)."""

    def __init__(self, series):
        self._series = series
        self.plane = getattr(series, "geometry", "axisymmetric") == "plane_strain"
        self.points = series.points  # (n_nodes, 2)
        self.cells = series.cells  # (n_cells, 3) triangles or (n_cells, 4) quadrilaterals
        self.fields = {name: Series(name, center, series.times)
                       for name, center in series.center.items()}

    def values(self, name: str, k: int) -> np.ndarray:
        """Values of field ``name`` at its k-th time (nodal (n, 3) or cell (m,), SI units)."""
        return self._series.values(name, k)


def read_xdmf(path: str) -> XdmfRun:
    """Read a run's fields.xdmf (see impact_fenics.xdmf)."""
    from .errors import InputError
    from .xdmf import FieldSeries

    if not os.path.isfile(path):
        raise InputError(f"'{path}' does not exist (a run directory holds fields.xdmf)")
    try:
        return XdmfRun(FieldSeries(path))
    except (ET.ParseError, ValueError, AttributeError, KeyError, OSError) as exc:
        raise InputError(f"'{path}' is not a fields.xdmf of impact_fenics ({exc})")


def _scalar(values: np.ndarray) -> np.ndarray:
    """A scalar per node or cell: the value, or the magnitude of a vector."""
    values = values.reshape(values.shape[0], -1)
    return values[:, 0] if values.shape[1] == 1 else np.linalg.norm(values, axis=1)


def _pick_times(series: Series, times: list[float] | None, n_default: int = 4) -> list[int]:
    """Indices of the stored times nearest to ``times`` (s), or n_default spread over the run
    after t = 0 (the initial state is blank: it is shown only when asked for)."""
    if times:
        picks = [int(np.argmin(np.abs(series.times - t))) for t in times]
    else:
        first = 1 if series.times.size > 1 else 0
        picks = np.linspace(first, series.times.size - 1, min(n_default, series.times.size - first))
        picks = [int(round(k)) for k in picks]
    return sorted(set(picks))


CLIP = (1.0, 99.0)  # percentiles of the colour range
MIN_WIDTH = 900  # pixels: the narrowest picture (its title and colour bar fit)


def _auto_region(points: np.ndarray, cells: np.ndarray, values: list[np.ndarray], center: str,
                 level: float = 0.05) -> tuple[float, float, float, float]:
    """(r0, r1, z0, z1) in m around where the field is: the cells (or nodes) whose |value|
    reaches ``level`` of the largest, padded by a tenth of the model size, within the model."""
    peak = max(float(np.nanmax(np.abs(v))) for v in values)
    lo, hi = points.min(axis=0), points.max(axis=0)
    if not peak > 0:
        return float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1])
    hot = np.zeros(len(cells) if center == "Cell" else len(points), dtype=bool)
    for v in values:
        hot |= np.abs(v) >= level * peak
    xy = points[cells[hot]].reshape(-1, 2) if center == "Cell" else points[hot]
    pad = 0.1 * float(np.ptp(points, axis=0).max())
    a, b = np.maximum(xy.min(axis=0) - pad, lo), np.minimum(xy.max(axis=0) + pad, hi)
    return float(a[0]), float(b[0]), float(a[1]), float(b[1])


def _run_facts(run_dir: str, data: XdmfRun) -> tuple[str, bool]:
    """(title, finite strain?) of a run: the scene's title and whether a body is at finite
    strain, from its summary.json; without one, the directory's name, and finite strain
    where the cells are quadrilaterals."""
    import json

    try:
        with open(os.path.join(run_dir, "summary.json")) as f:
            summary = json.load(f)
    except (OSError, ValueError):
        summary = {}
    if not isinstance(summary, dict):
        summary = {}
    title = summary.get("title") or _run_name(run_dir)
    bodies = summary.get("bodies")
    finite = (any(isinstance(b, dict) and b.get("strain") == "finite" for b in bodies.values())
              if isinstance(bodies, dict) and bodies else data.cells.shape[1] == 4)
    return str(title), finite


def _unit(field: str) -> tuple[float, str]:
    """Scale and unit label of a field for display."""
    if field in STRESSES:
        return 1e-6, "MPa"
    if field == "displacement":
        return 1e3, "mm"
    if field == "velocity":
        return 1.0, "m/s"
    if field == "temperature":
        return 1.0, "K"
    return 1.0, ""


@dataclass
class Picture:
    """One field render, planned: where it goes, its texts and what it draws.

    ``points`` (n, 2) the nodes at their drawn positions (r, z + scale x u, m); ``cells``
    every cell of the mesh; ``values`` per cell or node (``center``) in the unit of
    ``label``; ``frame`` (r0, r1, z0, z1), m, the drawn extent of the framed cells: the
    view fits it and the cells are cut at it (r to the right, z up, always)."""

    path: str
    title: str
    caption: str
    points: np.ndarray
    cells: np.ndarray
    values: np.ndarray
    center: str
    label: str
    clim: tuple[float, float]
    cmap: str
    frame: tuple[float, float, float, float]


def plan_pictures(run_dir: str, field: str = "sigma_zz", times: list[float] | None = None,
                  scale: float | None = None,
                  region: tuple[float, float, float, float] | str | None = "auto"
                  ) -> list[Picture]:
    """The pictures :func:`render_fields` draws (see there), without drawing them."""
    from .errors import InputError

    data = read_xdmf(os.path.join(run_dir, "fields.xdmf"))
    if field not in data.fields and data.plane:  # a plane-strain run
        from .geometry import PLANE_STRAIN, Geometry

        field = Geometry(PLANE_STRAIN).public(field)  # (the default sigma_zz: sigma_yy)
    if field not in data.fields:
        raise InputError(f"--field {field}: not in fields.xdmf (it has: "
                         f"{', '.join(sorted(data.fields))})")
    if scale is not None and not scale >= 0:
        raise InputError(f"--scale {scale}: must be >= 0")
    if region not in (None, "auto") and not (len(region) == 4 and region[0] < region[1]
                                             and region[2] < region[3]):
        raise InputError(f"--region {region}: give r0 < r1 and z0 < z1 (m)")
    name, finite = _run_facts(run_dir, data)
    series = data.fields[field]
    picks = _pick_times(series, times)
    disp = data.fields.get("displacement")
    u_at = {}
    for k in picks:
        t = series.times[k]
        if disp is not None:
            j = int(np.argmin(np.abs(disp.times - t)))
            u_at[k] = data.values("displacement", j)[:, :2]
        else:
            u_at[k] = np.zeros_like(data.points)
    size = float(np.ptp(data.points, axis=0).max())
    if scale is None:
        u_max = max(float(np.abs(u).max()) for u in u_at.values())
        scale = 1.0 if finite else (_round_scale(0.05 * size / u_max) if u_max > 0 else 0.0)
    factor, unit = _unit(field)
    values = {k: _scalar(data.values(field, k)) * factor for k in picks}
    if region == "auto":
        region = _auto_region(data.points, data.cells, list(values.values()), series.center)
    framed = np.ones(len(data.cells), dtype=bool)
    if region is not None:
        c = data.points[data.cells].mean(axis=1)
        framed = ((c[:, 0] >= region[0]) & (c[:, 0] <= region[1]) & (c[:, 1] >= region[2])
                  & (c[:, 1] <= region[3]))
        if not framed.any():
            raise InputError(f"--region {' '.join(f'{x:g}' for x in region)}: no cell has "
                             "its centre inside it")
    framed_nodes = np.unique(data.cells[framed])
    shown = np.concatenate([v[framed] if series.center == "Cell" else v[framed_nodes]
                            for v in values.values()])
    lo, hi = (float(x) for x in np.nanpercentile(shown, CLIP))
    clipped = lo > float(np.nanmin(shown)) or hi < float(np.nanmax(shown))
    diverging = field in STRESSES and field != "von_mises" and lo < 0 < hi
    if diverging:
        lo, hi = -max(-lo, hi), max(-lo, hi)
    label = f"{field} ({unit})" if unit else field
    if not scale:
        shape = "undeformed"
    elif scale == 1.0:
        shape = "true shape (displacement x 1)"
    else:
        shape = f"displacement x {scale:g}"
    pictures = []
    for k in picks:
        t = float(series.times[k])
        title = f"{name}: {label} at t = {t * 1e6:.2f} µs, {shape}"
        if clipped:
            title += f"\ncolours clipped to the {CLIP[0]:g}-{CLIP[1]:g} percentile range"
        xy = data.points + scale * u_at[k]
        lo_xy, hi_xy = xy[framed_nodes].min(axis=0), xy[framed_nodes].max(axis=0)
        frame = (float(lo_xy[0]), float(hi_xy[0]), float(lo_xy[1]), float(hi_xy[1]))
        pictures.append(Picture(os.path.join(run_dir, f"{field}_t{t:.6e}.png"), title,
                                _caption(frame, "deformed" if scale else "undeformed",
                                         ("x", "y") if data.plane else ("r", "z")), xy,
                                data.cells, values[k], series.center, label, (lo, hi),
                                "coolwarm" if diverging else "viridis", frame))
    return pictures


def _caption(frame: tuple[float, float, float, float], shape: str,
             axes: tuple[str, str] = ("r", "z")) -> str:
    """The extent shown, (r0, r1, z0, z1) in m, in mm below a metre (a node on the axis
    at r = -4e-19, mesh round-off, printed as 0), and the orientation; ``axes`` the
    coordinates' names ((x, y) in plane strain)."""
    lo, hi = np.array(frame[::2]), np.array(frame[1::2])
    size = float(max(hi - lo))
    lo = np.where(np.abs(lo) < 1e-12 * size, 0.0, lo)
    hi = np.where(np.abs(hi) < 1e-12 * size, 0.0, hi)
    f, unit = (1e3, "mm") if size < 1.0 else (1.0, "m")
    a, b = axes
    return (f"shown: {a} {lo[0] * f:.4g} to {hi[0] * f:.4g} {unit}, {b} {lo[1] * f:.4g} to "
            f"{hi[1] * f:.4g} {unit} ({shape}); {a} to the right, {b} up")


def render_fields(run_dir: str, field: str = "sigma_zz", times: list[float] | None = None,
                  scale: float | None = None, width: int = 1400,
                  region: tuple[float, float, float, float] | str | None = "auto") -> list[str]:
    """Render ``field`` on the deformed mesh at the stored times nearest to ``times`` (s).

    The displacement is multiplied by ``scale``. By default a finite-strain run is drawn
    at 1, its true shape; a small-strain run at the factor that shows the largest
    displacement of the chosen times as 5 % of the model size. The factor is stated in
    each title. ``region`` (r0, r1, z0, z1), in m of the undeformed body, frames the
    picture around the cells whose centre lies inside it; "auto" around the cells where
    |field| reaches 5 % of its largest value, with a margin of a tenth of the model
    size; None frames the whole model. The picture shows the frame: the cells across
    its edges are cut there, so the edges are straight lines, never the cells' outline,
    and the framed cells are shown whole. The colour
    range is that of the framed cells, clipped to their 1st-99th percentile (said in the
    title when it clips). Every picture has r to the right and z up (as ParaView shows
    fields.xdmf); its caption gives the drawn extent of the framed cells. The title is
    the scene's (summary.json; else the directory's name). One PNG per time in
    ``run_dir``, named ``<field>_t<time in s>.png`` (``width`` pixels wide at most);
    returns their paths."""
    if "dolfinx.cpp" in sys.modules:
        if os.environ.get("IMPACT_FENICS_RENDER_CHILD"):
            raise RuntimeError("the rendering process loaded dolfinx (VTK cannot share it)")
        plan_pictures(run_dir, field, times, scale, region)  # bad input: said here
        return _render_in_fresh_process(run_dir, field, times, scale, width, region)
    written = []
    for picture in plan_pictures(run_dir, field, times, scale, region):
        _render(picture, width)
        written.append(picture.path)
    return written


def _render_in_fresh_process(run_dir: str, field: str, times: list[float] | None,
                             scale: float | None, width: int, region) -> list[str]:
    """Run :func:`render_fields` in a new interpreter. VTK's C++ library aborts when it is
    loaded after dolfinx's in one process (they bind each other's libstdc++ symbols), so a
    process that ran a simulation renders through a child that never imports dolfinx."""
    import json
    import subprocess

    code = ("import json, sys; from impact_fenics.plotting import render_fields; "
            "print(json.dumps(render_fields(*json.loads(sys.argv[1]))))")
    from .compat import clean_launcher_env  # dolfinx is loaded already here

    env = clean_launcher_env()
    env["IMPACT_FENICS_RENDER_CHILD"] = "1"  # never spawn again from the child
    proc = subprocess.run([sys.executable, "-c", code,
                           json.dumps([run_dir, field, times, scale, width, region])],
                          capture_output=True, text=True, env=env)
    if proc.returncode != 0:
        last = (proc.stderr.strip().splitlines() or ["no message"])[-1]
        raise RuntimeError(f"rendering in a separate process failed: {last}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _round_scale(s: float) -> float:
    """s rounded down to 1, 2 or 5 times a power of ten (a factor easy to read)."""
    exp = np.floor(np.log10(s))
    for m in (5.0, 2.0, 1.0):
        if m * 10 ** exp <= s:
            return float(m * 10 ** exp)
    return float(10 ** exp)


def _render(pic: Picture, width: int) -> None:
    """Draw ``pic`` into its PNG: the cells cut at its frame (straight edges), r to the
    right and z up, the view fitted to the frame; a tall frame makes a narrower picture
    (at least MIN_WIDTH pixels)."""
    if not os.environ.get("DISPLAY"):
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import pyvista as pv

    cells = pic.cells
    points = np.column_stack([pic.points, np.zeros(len(pic.points))])
    npc = cells.shape[1]  # 3: triangles; 4: quadrilaterals (finite strain), nodes in cycle order
    vtk_cells = np.column_stack([np.full(len(cells), npc), cells]).ravel()
    kind = pv.CellType.TRIANGLE if npc == 3 else pv.CellType.QUAD
    grid = pv.UnstructuredGrid(vtk_cells, np.full(len(cells), kind), points)
    if pic.center == "Cell":
        grid.cell_data[pic.label] = pic.values
    else:
        grid.point_data[pic.label] = pic.values
    r0, r1, z0, z1 = pic.frame
    lo, hi = pic.points.min(axis=0), pic.points.max(axis=0)
    if lo[0] < r0 or hi[0] > r1 or lo[1] < z0 or hi[1] > z1:  # crop: cut the cells at the frame
        grid = grid.clip_box((r0, r1, z0, z1, -1.0, 1.0), invert=False)
    along, across = max(r1 - r0, 1e-300), max(z1 - z0, 1e-300)  # horizontal, vertical
    plot_h = float(np.clip(0.92 * width * across / along, 200, 1600))
    width = int(min(width, max(MIN_WIDTH, plot_h * along / across / 0.92)))
    plot_w = 0.92 * width
    # the title wrapped to the picture's width (font size 11: about 12 pixels a character)
    lines = [line for part in pic.title.split("\n")
             for line in textwrap.wrap(part, max(20, width // 14))]
    margin_top, margin_bottom = 30 + 20 * len(lines), 150  # pixels: title, colour bar
    height = int(plot_h / 0.92) + margin_top + margin_bottom
    plotter = pv.Plotter(off_screen=True, window_size=(width, height))
    plotter.set_background("white")
    plotter.add_mesh(grid, scalars=pic.label, cmap=pic.cmap, clim=pic.clim, lighting=False,
                     scalar_bar_args={"title": pic.label, "color": "black", "vertical": False,
                                      "position_x": 0.25, "position_y": 0.04,
                                      "width": 0.5, "height": 0.08, "fmt": "%.3g"})
    plotter.add_text("\n".join(lines), position="upper_edge", font_size=11, color="black")
    plotter.add_text(pic.caption, position="lower_left", font_size=8, color="gray")
    plotter.view_xy()
    plotter.enable_parallel_projection()
    # world units per pixel so that the frame fills the space between title and bar
    per_px = max(along / plot_w, across / plot_h)
    centre = np.array([0.5 * (r0 + r1), 0.5 * (z0 + z1), 0.0])
    centre[1] -= per_px * 0.5 * (margin_bottom - margin_top)  # the picture above the bar
    camera = plotter.camera
    offset = np.array(camera.position) - np.array(camera.focal_point)
    camera.focal_point = tuple(centre)
    camera.position = tuple(centre + offset)
    camera.parallel_scale = 0.5 * height * per_px
    plotter.screenshot(pic.path)
    plotter.close()
