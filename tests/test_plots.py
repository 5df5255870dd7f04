"""Pictures: history and energy PNGs after every run, field renders from the XDMF.

Oracles: the XDMF/HDF5 reader must give back what dolfinx evaluated during the
run (a u_z probe is the nodal u_z interpolated at its point, a sigma_zz probe the
DG0 value of its cell, at the same step), the mesh
sizes of the summary, and the specification of the pictures (PNG files that
hold a drawing: many colours, neither blank nor filled).
"""
import json
import os

import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics import cli, plotting
from roundoff import rounding
from scene_texts import BAR, PAIR, launch, replace

serial_only = pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="launches processes: serial only")

SCENE = replace(BAR, "[[probes]]", """[[probes]]
name = "s_mid"
point = [0.01, 0.05]
quantity = "sigma_zz"

[[probes]]""")


def _image(path: str) -> np.ndarray:
    import matplotlib.image as mpimg

    return mpimg.imread(path)[..., :3]


def _is_drawing(path: str, min_colours: int = 20) -> bool:
    """A PNG of reasonable size, many colours, neither blank nor filled."""
    rgb = _image(path)
    colours = np.unique((rgb * 255).astype(np.uint8).reshape(-1, 3), axis=0)
    inked = float(np.any(rgb < 0.9, axis=2).mean())
    return min(rgb.shape[:2]) >= 300 and len(colours) >= min_colours and 0.01 < inked < 0.95


def _coloured_fraction(path: str) -> float:
    """Share of the pixels with a saturated colour (the rendered field, not text)."""
    rgb = _image(path)
    hi, lo = rgb.max(axis=2), rgb.min(axis=2)
    return float(((hi - lo) > 0.25 * np.maximum(hi, 1e-9)).mean())


@pytest.fixture(scope="module")
def bar_run(tmp_path_factory):
    base = MPI.COMM_WORLD.bcast(str(tmp_path_factory.mktemp("plots")), root=0)
    scene = os.path.join(base, f"bar{MPI.COMM_WORLD.rank}.toml")
    with open(scene, "w") as f:
        f.write(SCENE)
    out = os.path.join(base, "bar")
    assert cli.main(["run", scene, "--out", out, "--quiet"]) == 0
    return out


def test_history_and_energy_pictures(bar_run, tmp_path):
    for name in ("history.png", "energy.png"):
        assert _is_drawing(os.path.join(bar_run, name)), name
    out = MPI.COMM_WORLD.bcast(str(tmp_path / "pair"), root=0)
    scene = tmp_path / "pair.toml"
    scene.write_text(PAIR)
    assert cli.main(["run", str(scene), "--out", out, "--quiet"]) == 0
    assert _is_drawing(os.path.join(out, "history.png"))  # probe, contact force and gap panels


def test_no_pictures_when_switched_off(tmp_path):
    out = MPI.COMM_WORLD.bcast(str(tmp_path / "off"), root=0)
    scene = tmp_path / "off.toml"
    scene.write_text(replace(SCENE, "output_every = 10", "output_every = 10\nplots = false"))
    assert cli.main(["run", str(scene), "--out", out, "--quiet"]) == 0
    assert os.path.isfile(os.path.join(out, "summary.json"))
    assert not os.path.exists(os.path.join(out, "history.png"))


def test_xdmf_reader_gives_back_the_probes(bar_run):
    data = plotting.read_xdmf(os.path.join(bar_run, "fields.xdmf"))
    with open(os.path.join(bar_run, "summary.json")) as f:
        summary = json.load(f)
    assert data.cells.shape == (summary["n_cells"], 3)  # every cell once, on any rank count
    assert 2 * data.points.shape[0] >= summary["n_dofs"]  # a node of two pieces is in both
    history = np.genfromtxt(os.path.join(bar_run, "history.csv"), delimiter=",", names=True)
    centroids = data.points[data.cells].mean(axis=1)
    point = np.array([0.01, 0.05])  # the probes' point (a node of the bar's mesh)
    cell = int(np.argmin(np.linalg.norm(centroids - point, axis=1)))
    # the point's barycentric coordinates in that cell (a cell touching the node: the
    # field is continuous there, so any of them gives its value)
    a, b, c = data.points[data.cells[cell]][:, :2]
    det = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])
    l1 = ((b[0] - point[0]) * (c[1] - point[1]) - (c[0] - point[0]) * (b[1] - point[1])) / det
    l2 = ((c[0] - point[0]) * (a[1] - point[1]) - (a[0] - point[0]) * (c[1] - point[1])) / det
    w = np.array([l1, l2, 1.0 - l1 - l2])
    assert np.all(w >= -1e-9)  # the cell holds the point
    # the mesh's node is the point to its generator's round-off, delta: a neighbouring
    # cell's interpolation there differs by at most the jump of the gradient times delta,
    # 2 x (2 max|u| / h) delta
    delta = float(np.min(np.linalg.norm(np.array([a, b, c]) - point, axis=1)))
    u_series, s_series = data.fields["displacement"], data.fields["sigma_zz"]
    assert s_series.center == "Cell" and u_series.center == "Node"
    assert np.array_equal(u_series.times, s_series.times) and u_series.times.size == 11
    checked = 0
    for k, t in enumerate(u_series.times):
        row = np.flatnonzero(history["time"] == t)  # both n dt, written with all 17 digits
        if row.size == 0:  # t = 0: history starts after the first step
            continue
        nodal = data.values("displacement", k)[data.cells[cell]]
        u_z = float(w @ nodal[:, 1])
        s_zz = data.values("sigma_zz", k)[cell]
        # the probe and the test: the interpolation at the point, the weights from
        # differences of coordinates up to 0.1 m on cells of h = 0.01 m (10 of the
        # digits' worth cancel), about 6 roundings each way, then 3 products and 2 sums
        # on the nodal values; the stress, on each path a strain from the 6 nodal values (rounded on E |u| / h,
        # h = 0.01 m, E = 200 GPa) and the stress: about 24 roundings
        u_bound = (rounding(2 * 6 * 0.1 / 0.01 + 5, np.abs(nodal[:, 1]).max())
                   + 4 * np.abs(nodal[:, 1]).max() / 0.01 * delta)
        assert abs(u_z - history["u_mid"][row[0]]) <= u_bound
        s_round = rounding(2 * 24, 200e9 * np.abs(nodal).max() / 0.01)
        assert abs(s_zz - history["s_mid"][row[0]]) <= s_round
        checked += 1
    assert checked == u_series.times.size - 1


def test_plot_command_renders_the_field(bar_run):
    t = plotting.read_xdmf(os.path.join(bar_run, "fields.xdmf")).fields["sigma_zz"].times
    code = cli.main(["plot", bar_run, "--times", str(t[4] + 1e-9), str(t[8]), "--field",
                     "sigma_zz"])
    assert code == 0
    if MPI.COMM_WORLD.rank == 0:
        for time in (t[4], t[8]):
            path = os.path.join(bar_run, f"sigma_zz_t{time:.6e}.png")
            assert _is_drawing(path, min_colours=50)
            assert _coloured_fraction(path) > 0.05  # the coloured mesh, not only text
    MPI.COMM_WORLD.barrier()


@serial_only
def test_plot_command_line(bar_run):
    proc = launch(["plot", bar_run, "--field", "von_mises", "--scale", "100"])
    assert proc.returncode == 0, proc.stderr
    written = proc.stdout.split()
    assert len(written) == 4 and all(_is_drawing(p) for p in written)  # four times by default
    proc = launch(["plot", bar_run, "--field", "sigma_xx"])
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert proc.returncode == 2 and len(lines) == 1
    assert lines[0].startswith("error: --field sigma_xx: not in fields.xdmf (it has: ")
    proc = launch(["plot", bar_run + "_nowhere"])
    assert proc.returncode == 2 and proc.stderr.startswith("error: run directory ")


def test_default_frames_skip_the_initial_state():
    series = plotting.Series("sigma_zz", "Cell", np.linspace(0.0, 1e-4, 11))
    assert plotting._pick_times(series, None) == [1, 4, 7, 10]  # t = 0 only when asked for
    assert plotting._pick_times(series, [0.0]) == [0]


def test_auto_region_frames_where_the_field_is():
    """A field that lives only in the cells with r < 0.2, z > 0.8 of the unit square: the
    zoom covers them, padded by a tenth of the model, and no more."""
    n = 10
    r, z = np.meshgrid(np.linspace(0, 1, n + 1), np.linspace(0, 1, n + 1), indexing="ij")
    points = np.column_stack([r.ravel(), z.ravel()])
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    cells = np.concatenate([np.column_stack([idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(),
                                             idx[1:, 1:].ravel()]),
                            np.column_stack([idx[:-1, :-1].ravel(), idx[1:, 1:].ravel(),
                                             idx[:-1, 1:].ravel()])])
    c = points[cells].mean(axis=1)
    values = np.where((c[:, 0] < 0.2) & (c[:, 1] > 0.8), 1.0, 0.0)
    r0, r1, z0, z1 = plotting._auto_region(points, cells, [values], "Cell")
    assert (r0, z1) == (0.0, 1.0)  # clipped to the model
    # the hot cells' nodes (linspace: 2 roundings) + a tenth of the extent (2 more)
    assert abs(r1 - 0.3) <= rounding(4) and abs(z0 - 0.7) <= rounding(4)


# a soft J2 target under the tiny pair's impact, with a probe of every kind
PLASTIC = replace(replace(PAIR, '[bodies.target]\nmaterial = "steel"',
                          '[bodies.target]\nmaterial = "soft"\n\n[materials.soft]\nmodel = "j2"\n'
                          'E = 200e9\nnu = 0.3\ndensity = 7850.0\nyield_stress = 1e6\n'
                          'hardening = 1e9'),
                  'quantity = "sigma_zz"\n', 'quantity = "sigma_zz"\n' + "".join(
                      f'\n[[probes]]\nname = "{q}_t"\npoint = [0.01, 0.005]\nquantity = "{q}"\n'
                      for q in ("von_mises", "u_z", "eps_p_eq", "yielded")))


@pytest.fixture(scope="module")
def plastic_run(tmp_path_factory):
    base = MPI.COMM_WORLD.bcast(str(tmp_path_factory.mktemp("plastic")), root=0)
    scene = os.path.join(base, f"plastic{MPI.COMM_WORLD.rank}.toml")
    with open(scene, "w") as f:
        f.write(PLASTIC)
    out = os.path.join(base, "plastic")
    assert cli.main(["run", scene, "--out", out, "--quiet"]) == 0
    return out


def _table(path: str) -> dict[str, np.ndarray]:
    data = np.genfromtxt(path, delimiter=",", names=True)
    return {name: np.atleast_1d(data[name]) for name in data.dtype.names}


def test_energy_picture_of_a_plastic_run(plastic_run):
    """energy.png draws the plastic work, and its total is the sum the scheme conserves:
    kinetic + strain + plastic work (the very sum of the table's columns), which follows
    the initial energy plus the work of the load and of the contact (drawn too) to the
    balance error of the run."""
    from impact_fenics.report import ROUND_OFF

    e = _table(os.path.join(plastic_run, "energy.csv"))
    curves = {name: y for name, _, y in plotting.energy_curves(e)}
    assert e["plastic_work"][-1] > 0
    assert {"kinetic", "strain", "plastic_work", "total", "external_work",
            "balance"} <= set(curves)
    # the pairs touch at t = 0: the first step's impact is in the first row's contact work
    # (the ledger's E_0 is the state before it), drawn when it is above the round-off
    # threshold of the console's line
    scale = max(np.abs(e[k]).max() for k in ("kinetic", "strain", "plastic_work", "total",
                                             "external_work", "contact_work"))
    assert ("contact_work" in curves) == (np.abs(e["contact_work"]).max() > ROUND_OFF * scale)
    assert np.array_equal(curves["total"], e["kinetic"] + e["strain"] + e["plastic_work"])
    # the balance: E_0 + the drawn work terms (a sum of 3: 4 roundings), E_0 read from the
    # first row (its total less its balance error and work terms: 3 more roundings, on
    # terms within the scale); a work term left out as round-off is missing from it by
    # its size
    scale = np.abs(e["total"]).max()
    left_out = sum(np.abs(e[k]).max() for k in ("external_work", "contact_work")
                   if k not in curves)
    assert np.abs(curves["balance"] - curves["total"]).max() <= \
        (e["balance_error_rel"].max() + rounding(7)) * scale + left_out
    assert all(np.any(y != 0.0) for name, y in curves.items() if name != "strain")
    assert _is_drawing(os.path.join(plastic_run, "energy.png"))
    # a run without plastic work: no such curve
    e = _table(os.path.join(plastic_run, "energy.csv"))
    e["plastic_work"][:] = 0.0
    assert "plastic_work" not in {name for name, _, _ in plotting.energy_curves(e)}


def test_history_picture_draws_every_probe(plastic_run):
    """Every probe column of history.csv is in a panel of history.png: stresses, u_z,
    eps_p_eq and yielded alike."""
    with open(os.path.join(plastic_run, "summary.json")) as f:
        summary = json.load(f)
    h = _table(os.path.join(plastic_run, "history.csv"))
    probes = [("s", "sigma_zz")] + [(f"{q}_t", q) for q in ("von_mises", "u_z", "eps_p_eq",
                                                            "yielded")]
    drawn = {name for _, curves in plotting.probe_panels(h, probes) for name, _ in curves}
    assert drawn == {name for name, _ in probes}
    assert h["eps_p_eq_t"][-1] > 0 and h["yielded_t"][-1] == 1.0
    assert summary["title"] == "tiny impact"
    assert _is_drawing(os.path.join(plastic_run, "history.png"))


# ----------------------------------------------------------------------------- field pictures
def _taylor_text() -> str:
    from scene_texts import ROOT

    with open(os.path.join(ROOT, "scenes", "taylor_bar.toml")) as f:
        text = f.read()
    text = replace(text, "n_r = 8", "n_r = 2")
    return replace(text, "t_end = 80e-6", "t_end = 20e-6")


def _run(base: str, name: str, text: str) -> str:
    scene = os.path.join(base, f"{name}{MPI.COMM_WORLD.rank}.toml")
    with open(scene, "w") as f:
        f.write(text)
    out = os.path.join(base, name)
    assert cli.main(["run", scene, "--out", out, "--quiet"]) == 0
    return out


@pytest.fixture(scope="module")
def taylor_run(tmp_path_factory):
    base = MPI.COMM_WORLD.bcast(str(tmp_path_factory.mktemp("taylor")), root=0)
    return _run(base, "taylor", _taylor_text())


@pytest.fixture(scope="module")
def punch_run(tmp_path_factory):
    from scene_texts import RIGID

    base = MPI.COMM_WORLD.bcast(str(tmp_path_factory.mktemp("punch")), root=0)
    return _run(base, "punch", 'title = "small punch"\n' + RIGID)


def _extent(caption: str) -> tuple[float, float, float, float]:
    """(r0, r1, z0, z1) of a caption 'shown: r A to B mm, z C to D mm (...)' in mm."""
    words = caption.replace(",", "").split()
    r = words.index("r")
    z = words.index("z")
    return (float(words[r + 1]), float(words[r + 3]), float(words[z + 1]), float(words[z + 3]))


def test_a_finite_strain_run_is_drawn_at_its_true_shape(taylor_run):
    """The Taylor bar (finite strain) is drawn at displacement x 1 by default, under the
    scene's title; the caption gives the deformed extent: z up to the length the run
    measured (the top of the axis, summary.json), r out to at least the impact face's
    radius. An explicit --scale still rules."""
    with open(os.path.join(taylor_run, "summary.json")) as f:
        s = json.load(f)
    data = plotting.read_xdmf(os.path.join(taylor_run, "fields.xdmf"))
    (last,) = plotting.plan_pictures(taylor_run, "von_mises", [s["t_end"]], region=None)
    assert last.title.startswith("Taylor bar: von_mises (MPa) at t = 20.00 µs, true shape "
                                 "(displacement x 1)")
    u = data.values("displacement", data.fields["displacement"].times.size - 1)[:, :2]
    assert np.array_equal(last.points, data.points + u)
    r0, r1, z0, z1 = _extent(last.caption)
    assert (r0, z0) == (0.0, 0.0) and "(deformed)" in last.caption
    assert z1 == float(f"{s['final_length'] * 1e3:.4g}")  # the printed digits
    assert r1 >= float(f"{s['final_face_radius'] * 1e3:.4g}") > 3.2  # wider than at rest
    (half,) = plotting.plan_pictures(taylor_run, "von_mises", [s["t_end"]], scale=0.5)
    assert "displacement x 0.5" in half.title


def test_the_frame_is_the_deformed_extent_of_the_framed_cells(bar_run):
    """A region frames the cells whose undeformed centre lies in it; the picture's frame
    (and caption) is the extent of their nodes at the drawn positions, every cell is
    handed to the drawing (it cuts them at the frame), and the small-strain scale shows
    the largest displacement as 5 % of the model, rounded down to 1, 2 or 5 x 10^k."""
    data = plotting.read_xdmf(os.path.join(bar_run, "fields.xdmf"))
    region = (0.0, 0.015, 0.02, 0.06)
    (pic,) = plotting.plan_pictures(bar_run, "sigma_zz", [5e-6], region=region)
    c = data.points[data.cells].mean(axis=1)
    inside = ((c[:, 0] >= region[0]) & (c[:, 0] <= region[1]) & (c[:, 1] >= region[2])
              & (c[:, 1] <= region[3]))
    nodes = np.unique(data.cells[inside])
    k = int(np.argmin(np.abs(data.fields["displacement"].times - 5e-6)))
    u = data.values("displacement", k)[:, :2]
    scale = float(pic.title.split("displacement x ")[1].split()[0])
    u_max = np.abs(u).max()
    assert 0.02 * 0.1 < scale * u_max <= 0.05 * 0.1  # 5 % of the model size, rounded down
    assert f"{scale:.0e}"[0] in "125"
    xy = data.points + scale * u
    assert pic.frame == (xy[nodes, 0].min(), xy[nodes, 0].max(), xy[nodes, 1].min(),
                         xy[nodes, 1].max())
    assert np.array_equal(pic.points, xy) and pic.cells.shape == data.cells.shape


def _coloured(rgb: np.ndarray) -> np.ndarray:
    hi, lo = rgb.max(axis=2), rgb.min(axis=2)
    return (hi - lo) > 0.25 * np.maximum(hi, 1e-9)


def test_pictures_keep_r_to_the_right_and_z_up_with_straight_edges(taylor_run, punch_run):
    """One orientation for every picture, r to the right and z up: the tall Taylor bar makes
    a picture taller than wide, the wide punch block one wider than tall. A region that
    cuts the block at r = 0.15 m ends the coloured mesh at one column of pixels in every
    row (the cells are cut at the frame: no sawtooth of whole cells)."""
    if MPI.COMM_WORLD.rank == 0:
        (tall,) = plotting.render_fields(taylor_run, "von_mises", [20e-6], region=None)
        h, w = _image(tall).shape[:2]
        assert h > w
        (wide,) = plotting.render_fields(punch_run, "sigma_zz", [2e-6], region=None)
        h, w = _image(wide).shape[:2]
        assert w > h
        (cut,) = plotting.render_fields(punch_run, "von_mises", [2e-6], scale=0.0,
                                        region=(0.0, 0.15, -0.1, 0.0))
        rgb = _image(cut)
        mesh = _coloured(rgb)[80: rgb.shape[0] - 160]  # between the title and the colour bar
        rows = np.flatnonzero(mesh.any(axis=1))
        right = np.array([np.flatnonzero(mesh[i])[-1] for i in rows])
        assert rows.size > 100 and np.ptp(right) <= 1
        assert "small punch: von_mises" in plotting.plan_pictures(punch_run, "von_mises",
                                                                 [2e-6])[0].title
    MPI.COMM_WORLD.barrier()


def _wide_ledgers() -> tuple[dict, dict, list]:
    """History and energy columns whose tick labels are as wide as a run's get: a probe
    stress to -1500 MPa ("-1500"), a probe displacement to -2.5e-6 m ("-0.0025" mm), a
    contact force of 5e7 N (offset text "1e7"), rigid body columns, an energy of
    -123456 J ("-120000"), a balance error over four decades (log ticks "10^-17") and a
    time axis whose last tick, "100000" (µs), sits at the right edge of the view (the
    data's end, 95240 µs, plus matplotlib's 5 % margin: 100002 µs)."""
    t = np.linspace(0.0, 0.09524, 201)
    s = np.sin(np.linspace(0.0, 3.0, t.size))
    history = {"time": t, "s_mid": -1.5e9 * s, "u_mid": -2.5e-6 * s, "eps": 0.06 * s,
               "contact_force": 5e7 * s, "min_gap": -1e-4 * s, "striker_u": -3e-3 * s,
               "striker_v": 27.0 * s}
    probes = [("s_mid", "sigma_zz"), ("u_mid", "u_z"), ("eps", "eps_p_eq")]
    energy = {"time": t, "kinetic": 122041.0 * (1 - s), "strain": 4875.0 * s,
              "plastic_work": 52240.0 * s, "total": np.full(t.size, 122041.0),
              "contact_work": -123456.0 * s, "balance_error_rel": np.logspace(-17, -13, t.size)}
    return history, energy, probes


def test_the_fixed_layout_keeps_every_text_in_the_picture():
    """history.png and energy.png are laid out once with fixed margins (no layout engine
    at save): with the widest tick labels of a run, everything drawn of each panel (its
    title, axis and tick labels, offset texts, legend: the renderer's tight box of the
    panel) lies inside the picture, and no text of a panel reaches into another panel.
    Geometry of the renderer's extents in pixels at the saved dpi: containment is exact,
    no tolerance."""
    history, energy, probes = _wide_ledgers()
    figures = [plotting.history_figure(history, probes, "a run"),
               plotting.energy_figure(energy, "a run")]
    for fig in figures:
        fig.set_dpi(110)  # as saved
        fig.canvas.draw()
        renderer = fig.canvas.get_renderer()
        page = fig.bbox
        for ax in fig.axes:
            box = ax.get_tightbbox(renderer)
            assert (page.x0 <= box.x0 and box.x1 <= page.x1 and page.y0 <= box.y0
                    and box.y1 <= page.y1), (ax.get_ylabel(), box, page)
            texts = [ax.yaxis.get_tightbbox(renderer), ax.xaxis.get_tightbbox(renderer),
                     ax.title.get_window_extent(renderer) if ax.get_title() else None]
            for other in fig.axes:
                if other is not ax:
                    frame = other.get_window_extent(renderer)
                    for text in texts:
                        assert text is None or not text.overlaps(frame), (
                            ax.get_ylabel(), text, frame)
