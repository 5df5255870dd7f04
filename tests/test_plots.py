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
        row = np.flatnonzero(np.isclose(history["time"], t, rtol=1e-9, atol=0))
        if row.size == 0:  # t = 0: history starts after the first step
            continue
        u_z = data.values("displacement", k)[data.cells[cell], 1].mean()
        s_zz = data.values("sigma_zz", k)[cell]
        scale_u = np.abs(history["u_mid"]).max()
        scale_s = np.abs(history["s_mid"]).max()
        assert abs(u_z - history["u_mid"][row[0]]) <= 1e-10 * scale_u
        assert abs(s_zz - history["s_mid"][row[0]]) <= 1e-10 * scale_s
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
    assert abs(r1 - 0.3) < 1e-12 and abs(z0 - 0.7) < 1e-12  # the hot cells' nodes + 0.1


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
    e = _table(os.path.join(plastic_run, "energy.csv"))
    curves = {name: y for name, _, y in plotting.energy_curves(e)}
    assert e["plastic_work"][-1] > 0
    assert {"kinetic", "strain", "plastic_work", "total", "external_work", "contact_work",
            "balance"} <= set(curves)
    assert np.array_equal(curves["total"], e["kinetic"] + e["strain"] + e["plastic_work"])
    scale = np.abs(e["total"]).max()
    assert np.abs(curves["balance"] - curves["total"]).max() <= \
        (e["balance_error_rel"].max() + 4 * np.finfo(float).eps) * scale
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
