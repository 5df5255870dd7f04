"""The strain-gauge probe: (u_z(r, z + l/2) - u_z(r, z - l/2)) / l, compression negative.

Oracles:

* exactness: interpolation (barycentric on triangles, bilinear on quadrilaterals) is
  exact for a linear field, so under u_z = a z + b r + c set directly on the nodes every
  gauge reads a to round-off, on a P1 mesh and on a Q1 mesh, on the surface, inside and on
  the axis;
* physics: the nu = 0 bar under an end pressure pulse (tests/test_wave.py's scene) carries
  the exact 1D wave eps_zz = -p / E: a gauge on the surface reads that plateau within the
  wave test's (h / l)^2 (l = c0 t_rise the ramp's length), and the ramp's half level
  arrives at the gauge's centre at z / c0 + t_rise / 2 within h / c0 (the mesh spreads a
  z-only field at the element scale) + dt (the history's sampling) + l_gauge / (2 c0) (the
  gauge averages over its length);
* the compiled step blocks record gauges as the Python steps do, bit for bit;
* a scene file's gauge runs through `impact-fenics run` into history.csv and reads the
  same on 1, 2 and 3 ranks to 1e-10 of its scale (the partitions only reorder sums);
  bad gauges are refused in one line, exit 2, nothing written.
"""
import os
import re

import numpy as np
import pytest
from mpi4py import MPI

from roundoff import rounding
from conftest import WAVE_GAUGE, WAVE_PEAK, WAVE_RISE, WAVE_STATIONS, wave_plateau
from scene_texts import (PAIR, ROOT, assert_ranks_agree, assert_refused, read_history,
                         replace, scene_on_every_rank)
from test_q1_probes import read_probes

from impact_fenics import cli, meshing
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.errors import InputError
from impact_fenics.materials import LinearElastic
from impact_fenics.probes import Probes, outer_radius
from impact_fenics.quad_meshes import quad_rectangle
from impact_fenics.simulation import Simulation

COMM = MPI.COMM_WORLD
serial_only = pytest.mark.skipif(COMM.size > 1, reason="launches processes: serial only")
E, RHO = 200e9, 7850.0


# ------------------------------------------------------------------ a linear field
A, B, C = 1.3e-3, -2.1e-3, 1e-4  # u_z = a z + b r + c (m); the gauge reads a
MESHES = {
    # an unstructured triangle mesh of a bar r <= 0.05, 0 <= z <= 0.3 (h = 1 cm)
    "p1": (lambda: meshing.bar(radius=0.05, length=0.3, h=0.01, structured=False, comm=COMM),
           "bar", [((0.05, 0.1234), 2e-3), ((0.0213, 0.2), 0.0137), ((0.0, 0.15), 0.05),
                   ((0.05, 0.29), 2e-3)]),
    # rectangles 0.01 x 0.03 m, r in [0, 0.04], z in [0.1, 0.25]
    "q1": (lambda: quad_rectangle(COMM, 0.0, 0.1, 0.04, 0.25, 4, 5, "body"),
           "body", [((0.04, 0.1777), 2e-3), ((0.0137, 0.16), 0.03), ((0.0, 0.2), 0.06),
                    ((0.02, 0.13), 0.06)]),
}


@pytest.mark.parametrize("kind", sorted(MESHES))
def test_gauge_reads_a_linear_field_exactly(kind):
    make, body, gauges = MESHES[kind]
    model = DeformableModel(make(), [Body(body, LinearElastic(E=E, nu=0.3, density=RHO))])
    xy = model.node_xy[: model.n_owned // 2]
    u_z = A * xy[:, 1] + B * xy[:, 0] + C
    u_owned = np.column_stack([0.7 * u_z, u_z]).ravel()  # any u_r: the gauge ignores it
    specs = [(f"g{k}", p, "strain_gauge", length) for k, (p, length) in enumerate(gauges)]
    got = read_probes(Probes(model, specs), u_owned)
    # round-off: each end's weights carry a few roundings (a 2x2 solve, or Newton's last
    # step), amplified by the cell's shape (< 4 here), and its sum takes 3-4 products: 64
    # roundings of the largest |u_z| per end (as the Q1 probes' test); the two ends' errors
    # add and the difference is divided by l
    U = 0.3 * abs(A) + 0.05 * abs(B) + abs(C)
    bound = [2 * rounding(64, U) / length + rounding(2, abs(A)) for _, length in gauges]
    if COMM.rank == 0:
        print(f"{kind} linear field: gauge - a = {np.abs(got - A).tolist()} of a = {A}; "
              f"bounds {bound}")
    assert np.all(np.abs(got - A) <= bound)


def test_probes_refuse_bad_gauges():
    """The Python path (Simulation.add_probe -> Probes): l <= 0, an end outside the mesh,
    ends in two bodies; each an InputError naming the gauge."""
    tm = meshing.coaxial_bars(radius=0.02, striker_length=0.04, target_length=0.04, h=0.01,
                              comm=COMM)
    steel = LinearElastic(E=E, nu=0.3, density=RHO)
    model = DeformableModel(tm, [Body("striker", steel), Body("target", steel)])
    for spec, words in ((("g", (0.02, 0.02), "strain_gauge", 0.0), "gauge length must be > 0"),
                        (("g", (0.02, 0.039), "strain_gauge", 0.004), "end (r=0.02, z=0.041"),
                        (("g", (0.02, 0.0), "strain_gauge", 0.01),
                         "ends lie in two bodies (striker and target)")):
        with pytest.raises(InputError, match="probe 'g': .*" + re.escape(words)):
            Probes(model, [spec])


def test_outer_radius_is_the_surface():
    """The largest r of the cells at a height: the bar's radius (its outer nodes lie on
    r = 0.05 m exactly), at a node's height and between; -inf above the mesh."""
    tm = meshing.bar(radius=0.05, length=0.3, h=0.01, structured=False, comm=COMM)
    for z in (0.0, 0.1234, 0.2, 0.3):
        assert outer_radius(tm.mesh, z) == 0.05
    assert outer_radius(tm.mesh, 0.31) == -np.inf


# ------------------------------------------------------------------ the nu = 0 wave
P0, T_RISE, STATIONS, GAUGE = WAVE_PEAK, WAVE_RISE, WAVE_STATIONS, WAVE_GAUGE


@pytest.mark.parametrize("h", [0.01, 0.005])
def test_gauge_reads_the_wave_plateau_and_arrival(wave_bars, h):
    sim = wave_bars[h]
    material = next(iter(sim.model.bodies.values())).material
    c0, dt = material.bar_wave_speed(), sim.settings.dt
    hist = sim.history.data()
    t = hist["time"]
    exact = -P0 / material.E  # the 1D wave's strain (compression negative)
    for k, z in enumerate(STATIONS):
        eps = hist[f"gauge_{k}"]
        plateau, arrival = wave_plateau(t, eps, exact)
        late = abs(arrival - (z / c0 + T_RISE / 2))
        if COMM.rank == 0:
            print(f"h = {h} m, gauge at z = {z} m: plateau {plateau:.6e} vs -p/E = {exact:.6e} "
                  f"(rel. error {abs(plateau / exact - 1):.2e}, bound {(h / 0.1) ** 2:.2e}); "
                  f"arrival error {late:.3e} s, bound {h / c0 + dt + GAUGE / (2 * c0):.3e} s")
        assert abs(plateau - exact) <= (h / 0.1) ** 2 * abs(exact)
        assert late <= h / c0 + dt + GAUGE / (2 * c0)


def test_gauges_in_compiled_steps_equal_python_steps(tmp_path_factory):
    """A P1 bar and a Q1 bar struck by an initial velocity (no loads: the loop runs compiled
    blocks), with gauges on the surface and inside: everything written is identical."""
    from impact_fenics.quad_meshes import quad_bar
    from impact_fenics.quad_meshes import tag_rectangle
    from test_step_block import _same, _settings

    meshes = {"p1": meshing.bar(radius=0.05, length=0.4, h=0.0125, structured=False, comm=COMM),
              "q1": tag_rectangle(quad_bar(COMM, 0.05, 0.4, 4, 32), "bar")}
    for kind, tm in meshes.items():
        def make(out, compiled):
            model = DeformableModel(tm, [Body("bar", LinearElastic(E=E, nu=0.3, density=RHO))])
            sim = Simulation(model, _settings(out, compiled, n_steps=80, output_every=20),
                             initial_velocity={"bar": (0.0, 5.0)})
            sim.add_probe("surface", (0.05, 0.2), "strain_gauge")
            sim.add_probe("inside", (0.0213, 0.3117), "strain_gauge", 0.02)
            return sim
        got = _same(make, tmp_path_factory, f"gauge_block_{kind}", expect_contact=False)
        assert np.max(np.abs(got["history.surface"])) > 0.0
        assert np.max(np.abs(got["history.inside"])) > 0.0


# ------------------------------------------------------------------ the scene file
with open(os.path.join(ROOT, "scenes", "elastic_wave.toml")) as f:
    WAVE = f.read()
SCENE = replace(replace(WAVE, "h = 0.005 ", "h = 0.01  "), "t_end = 1.5e-4", "t_end = 1e-4") + """
[[probes]]
name = "gauge_surface"
point = [0.05, 0.3]
quantity = "strain_gauge"

[[probes]]
name = "gauge_inside"
point = [0.0213, 0.45]
quantity = "strain_gauge"
length = 0.01

[[probes]]
name = "gauge_by_z"
z = 0.3
quantity = "strain_gauge"
"""


def test_scene_gauge_runs_and_reads_the_same_on_1_2_3_ranks(tmp_path_factory):
    """The scene through the CLI in this process (its history holds the gauge columns, the
    surface gauge the wave's plateau); in the serial pass also on 2 and 3 ranks, launched:
    every gauge value within 1e-10 of the column's largest (the partitions reorder the
    sums of each step: round-off, which the undamped wave does not amplify beyond it)."""
    base, scene = scene_on_every_rank(tmp_path_factory, "gauge_scene", SCENE)
    out = os.path.join(base, "n1")
    assert cli.main(["run", scene, "--out", out, "--quiet"]) == 0
    h1 = read_history(out)
    assert "gauge_surface" in h1 and "gauge_inside" in h1
    # placed by z alone it sits on the surface r = 0.05 m: the same gauge, the same column
    assert np.array_equal(h1["gauge_by_z"], h1["gauge_surface"])
    exact = -P0 / E
    assert np.min(h1["gauge_surface"]) < 0.5 * exact  # the pulse passed it, compressive
    if COMM.size > 1:
        return
    assert_ranks_agree(scene, base, h1, ("gauge_surface", "gauge_inside"))


BAD = [
    ('name = "gauge_inside"\npoint = [0.0213, 0.45]',
     'name = "gauge_inside"\npoint = [0.0213, 0.9995]',
     "error: [probes #6] the gauge's end (r=0.0213, z=1.004"),
    ("length = 0.01", "length = 0.0", "error: [probes #6] length = 0.0: must be > 0"),
    ("length = 0.01", "length = -0.002", "error: [probes #6] length = -0.002: must be > 0"),
    ('quantity = "u_z"        # m', 'quantity = "u_z"\nlength = 0.002',
     "error: [probes #2] length = 0.002: only a quantity = \"strain_gauge\""),
    ("z = 0.3\n", "z = 1.5\n", "error: [probes #7] z = 1.5: no cell of the mesh is at that height"),
    ("z = 0.3\n", "z = 0.3\npoint = [0.05, 0.3]\n",
     "error: [probes #7] z = 0.3: give point or z, not both"),
    ('quantity = "u_z"        # m', 'quantity = "u_z"\nz = 0.3',
     "error: [probes #2] z = 0.3: only a quantity = \"strain_gauge\" or \"section\" is placed "
     "by z alone"),
]


@serial_only
@pytest.mark.parametrize("edit", BAD, ids=["outside", "zero", "negative", "not_a_gauge",
                                          "z_outside", "z_and_point", "z_not_a_gauge"])
def test_bad_gauges_are_refused_in_one_line(tmp_path, edit):
    scene = tmp_path / "scene.toml"
    scene.write_text(replace(SCENE, edit[0], edit[1]))
    _refused(scene, tmp_path, edit[2])


@serial_only
def test_a_gauge_across_two_bodies_is_refused(tmp_path):
    """The tiny two-bar scene: striker z <= 0, target z >= 0; a gauge centred on the
    interface has an end in each."""
    scene = tmp_path / "scene.toml"
    scene.write_text(PAIR + '\n[[probes]]\nname = "g"\npoint = [0.02, 0.0]\n'
                     'quantity = "strain_gauge"\nlength = 0.01\n')
    _refused(scene, tmp_path, "error: [probes #2] the gauge's ends lie in two bodies "
                              "(striker and target)")


def _refused(scene, tmp_path, expected: str) -> None:
    out = tmp_path / "out"
    assert_refused(["run", str(scene), "--quiet", "--out", str(out)], expected, out)
