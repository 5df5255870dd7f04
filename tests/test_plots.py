"""Pictures: history and energy PNGs after every run, field renders from the XDMF.

Oracles: the XDMF/HDF5 reader must give back what dolfinx evaluated during the
run (a probe is the DG0 value of its cell: the nodal u_z averaged over the
cell's vertices, and the sigma_zz cell value, at the same step), the mesh
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
    cell = int(np.argmin(np.linalg.norm(centroids - [0.01, 0.05], axis=1)))
    u_series, s_series = data.fields["displacement"], data.fields["sigma_zz"]
    assert s_series.center == "Cell" and u_series.center == "Node"
    assert np.array_equal(u_series.times, s_series.times) and u_series.times.size == 11
    checked = 0
    for k, t in enumerate(u_series.times):
        row = np.flatnonzero(history["time"] == t)  # both n dt, written with all 17 digits
        if row.size == 0:  # t = 0: history starts after the first step
            continue
        nodal = data.values("displacement", k)[data.cells[cell]]
        u_z = nodal[:, 1].mean()
        s_zz = data.values("sigma_zz", k)[cell]
        # the probe and the writer: the mean of the cell's 3 nodal values (3 roundings);
        # the stress, on each path a strain from the 6 nodal values (rounded on E |u| / h,
        # h = 0.01 m, E = 200 GPa) and the stress: about 24 roundings
        scale_u = np.abs(history["u_mid"]).max()
        assert abs(u_z - history["u_mid"][row[0]]) <= rounding(3, scale_u)
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
