"""The plane-strain scene file from the command line: scenes/plane_strain_strip.toml runs on
1, 2 and 3 ranks (histories within 1e-10 of their largest value: the partitions reorder
each step's sums, round-off an undamped wave does not amplify), its fields are named for
plane strain in fields.xdmf and ParaView reads them so, its summary says the thickness;
what plane strain does not run yet, and keys of the other geometry, are refused in one
line. The physics of the scene is checked in tests/test_plane_strain.py."""
import json
import os

import numpy as np
import pytest
from mpi4py import MPI

from pvbatch_run import pvbatch_json
from scene_texts import (PAIR, RIGID, ROOT, assert_ranks_agree, assert_refused, launch,
                         read_history, replace)

SCENE = os.path.join(ROOT, "scenes", "plane_strain_strip.toml")
PLANE_FIELDS = {"sigma_xx", "sigma_yy", "sigma_out", "sigma_xy", "von_mises", "body_id"}
pytestmark = pytest.mark.skipif(MPI.COMM_WORLD.size > 1,
                                reason="launches its own runs (serial and under mpirun)")


@pytest.fixture(scope="module")
def serial(tmp_path_factory):
    base = tmp_path_factory.mktemp("plane_strain_strip")
    out = base / "n1"
    proc = launch(["run", SCENE, "--out", out], timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return str(base), str(out), proc.stdout


def test_runs_and_names_its_outputs(serial):
    base, out, stdout = serial
    assert "plane strain: masses, forces and energies per thickness t = 0.01 m" in stdout
    assert "sigma_yy in [" in stdout and "v_y " in stdout
    with open(os.path.join(out, "summary.json")) as f:
        summary = json.load(f)
    assert summary["geometry"] == {"kind": "plane_strain", "thickness": 0.01, "symmetry": None}
    assert {"sigma_yy_min", "sigma_yy_max"} <= set(summary["peak_stress"])
    # the slab's mass rho t A (kg), to the round-off of its sum over the 2,000 cells
    mass = summary["bodies"]["block"]["mass"]
    assert abs(mass - 7850.0 * 0.01 * 0.02 * 0.2) <= 2000 * 2.3e-16 * mass
    h = read_history(out)
    assert {"sigma_yy_mid", "sigma_out_mid", "u_y_bottom"} <= set(h)
    # on rollers sigma_out = nu (sigma_xx + sigma_yy) = nu / (1 - nu) sigma_yy (1D strain):
    # the two probes read the same cell at every step
    assert np.allclose(h["sigma_out_mid"], h["sigma_yy_mid"] / 3.0, rtol=1e-9, atol=1e-6)
    from impact_fenics.xdmf import FieldSeries

    series = FieldSeries(os.path.join(out, "fields.xdmf"))
    assert series.geometry == "plane_strain"
    assert set(series.center) == PLANE_FIELDS | {"displacement", "velocity"}


def test_opens_in_paraview(serial):
    _, out, _ = serial
    result = pvbatch_json(os.path.join(out, "fields.xdmf"), field="sigma_yy")
    if result is None:
        pytest.skip("pvbatch (ParaView) is not installed: the names were checked in the file")
    assert result["reader"] == "Xdmf3ReaderS"
    for step in result["steps"]:
        for block in step["blocks"]:
            assert set(block["arrays"]) == {"displacement", "velocity"} | PLANE_FIELDS
    lo, hi = result["sigma_zz_colour_range"]  # (the range of the field coloured by)
    assert lo < 0.0 and lo <= hi


def test_ranks_agree(serial):
    base, out, _ = serial
    assert_ranks_agree(SCENE, base, read_history(out),
                       ("sigma_yy_mid", "sigma_out_mid", "u_y_bottom"))


def test_plot_renders_sigma_yy_by_default(serial, tmp_path):
    _, out, _ = serial
    proc = launch(["plot", out])
    assert proc.returncode == 0, proc.stderr[-2000:]


STRIP = open(SCENE).read()


@pytest.mark.parametrize("old, new, expected", [
    ('geometry = "plane_strain"\n', "", "error: [plane_strain.toml, top level] thickness = 0.01"),
    ('facet = "left"\ncomponents = ["x"]\n', 'facet = "left"\ncomponents = ["r"]\n',
     "error: [fixed #1] components = [\"r\"]: must be a list of distinct components \"x\" and \"y\" (plane strain)"),
    ('quantity = "sigma_yy"', 'quantity = "sigma_zz"', "error: [probes #1] quantity"),
    ('thickness = 0.01        # m, the slab\'s thickness t\n', 'thickness = 0.0\n',
     "error: [plane_strain.toml, top level] thickness = 0"),
    ('thickness = 0.01        # m, the slab\'s thickness t\n', 'symmetry = "y=0"\n',
     "error: [plane_strain.toml, top level] symmetry"),
])
def test_refused(tmp_path, old, new, expected):
    scene = tmp_path / "plane_strain.toml"
    scene.write_text(replace(STRIP, old, new))
    assert_refused(["run", scene, "--out", tmp_path / "out"], expected, tmp_path / "out")


@pytest.mark.parametrize("text, expected", [
    (replace(RIGID, 'components = ["z"]', 'components = ["y"]'),
     "error: [contact #1] radius: a plane-strain rigid face has a half_width (m; |x| <= "
     "half_width) instead"),
])
def test_radius_refused(tmp_path, text, expected):
    """Node pairs, node to segment, rigid faces and the wall run in plane strain, friction
    too (tests/test_plane_strain_contact.py, tests/test_plane_strain_impact.py,
    tests/test_plane_strain_friction.py); a rigid face is sized by its half_width."""
    scene = tmp_path / "contact.toml"
    scene.write_text('geometry = "plane_strain"\n' + text)
    assert_refused(["run", scene, "--out", tmp_path / "out"], expected, tmp_path / "out")


def test_half_width_refused_in_axisymmetry(tmp_path):
    scene = tmp_path / "punch.toml"
    scene.write_text(replace(RIGID, "radius = 0.1\n", "half_width = 0.1\n"))
    assert_refused(["run", scene, "--out", tmp_path / "out"],
                   "error: [contact #1] half_width: an axisymmetric rigid face has a radius "
                   "(m) instead", tmp_path / "out")


def test_symmetry_refused_in_axisymmetry(tmp_path):
    scene = tmp_path / "pair.toml"
    scene.write_text('symmetry = "x=0"\n' + PAIR)
    assert_refused(["run", scene, "--out", tmp_path / "out"],
                   "error: [pair.toml, top level] symmetry", tmp_path / "out")


# the strip of J2 steel (perfectly plastic, sigma_y = 4 MPa) on rollers: uniaxial strain
J2_STRIP = replace(STRIP, "[materials.steel]\n",
                   '[materials.steel]\nmodel = "j2"\nyield_stress = 4e6\n') + """
[[probes]]
name = "eps_p_mid"
point = [0.01, 0.1]
quantity = "eps_p_eq"
"""


def test_j2_strip_runs_its_elastic_precursor_at_the_hel(tmp_path):
    """A path-dependent body in a plane-strain scene, on 1, 2 and 3 ranks. On rollers the
    strain is uniaxial (eps_xx = eps_out = 0), so sigma_xx = sigma_out and J2 yields where
    sigma_out - sigma_yy = sigma_y: the elastic precursor carries sigma_yy up to the
    Hugoniot elastic limit sigma_HEL = sigma_y (1 - nu) / (1 - 2 nu) = 6 MPa (the 10 MPa
    load reaches it at 3 us), the rest follows as a slower plastic wave
    (sqrt(K / rho) against sqrt((lambda + 2 G) / rho)). At the mid probe (y = 0.1 m) the
    precursor's plateau lasts from ~21 us to the plastic wave's arrival at ~27 us; read
    between 22.5 and 24.5 us it is sigma_HEL within (h / l)^2 (the wave test's plateau
    bound, l = c t_HEL the precursor's ramp length); at every output the probe's point
    satisfies the yield condition sigma_out - sigma_yy <= sigma_y to round-off (64 EPS),
    and it has flowed by the end."""
    scene = tmp_path / "j2_strip.toml"
    scene.write_text(J2_STRIP)
    out = tmp_path / "n1"
    proc = launch(["run", scene, "--out", out, "--quiet"], timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    h = read_history(out)
    sy, nu, E, rho, h_mesh = 4e6, 0.25, 200e9, 7850.0, 0.002
    hel = sy * (1.0 - nu) / (1.0 - 2.0 * nu)
    lam = mu = E / (2.0 * (1.0 + nu))  # nu = 1/4: lambda = G
    c = ((lam + 2.0 * mu) / rho) ** 0.5
    l_ramp = c * 5e-6 * hel / 10e6
    plateau = (h["time"] >= 22.5e-6) & (h["time"] <= 24.5e-6)
    assert plateau.sum() >= 3
    err = float(np.max(np.abs(h["sigma_yy_mid"][plateau] + hel)))
    print(f"precursor plateau: sigma_yy within {err:.4g} Pa of -sigma_HEL = {-hel:.4g} Pa "
          f"(bound {(h_mesh / l_ramp) ** 2 * hel:.3g} Pa)")
    assert err <= (h_mesh / l_ramp) ** 2 * hel
    q = h["sigma_out_mid"] - h["sigma_yy_mid"]
    print(f"largest sigma_out - sigma_yy {q.max()!r} Pa, sigma_y {sy!r} Pa; "
          f"eps_p_eq at the end {h['eps_p_mid'][-1]:.3g}")
    assert q.max() <= sy * (1.0 + 64 * 2.3e-16)
    assert h["eps_p_mid"][-1] > 0.0
    assert_ranks_agree(scene, str(tmp_path), h,
                       ("sigma_yy_mid", "sigma_out_mid", "u_y_bottom", "eps_p_mid"))
