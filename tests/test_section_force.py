"""The section probe: the axial force through a plane of a linear body's nodes (N,
compression positive), F_s = - sum over the plane's nodes of the z force K_below u.

Oracles:

* a linear field (u_r = b r, u_z = a z: uniform stress, which P1 and the B-bar Q1 carry
  exactly) gives the traction's resultant - sigma_zz pi R^2 to round-off, P1 and Q1;
* momentum: over a run the impulse sum_n h F_s^n plus the other forces' equals the change
  of z momentum of the body's nodes at and above the plane, to round-off (an identity of
  the scheme, derived in impact_fenics/section.py): a bar whose lower half is thrown
  against its upper half (no other force above the plane: compiled steps), P1 and Q1,
  and the nu = 0 bar under an end pressure (the Python steps);
* physics: in the nu = 0 bar's plateau the section carries p pi R^2 within the wave
  test's (h / l)^2 (l = c0 t_rise the ramp's length);
* the compiled step blocks record sections as the Python steps do, bit for bit;
* a scene file's section runs through `impact-fenics run` into history.csv and reads the
  same on 1, 2 and 3 ranks to 1e-10 of its scale; bad sections are refused in one line,
  exit 2, nothing written.
"""
import os

import numpy as np
import pytest
from mpi4py import MPI

from roundoff import rounding
from conftest import WAVE_PEAK, WAVE_RADIUS, WAVE_RISE, WAVE_STATIONS, wave_plateau
from scene_texts import (PAIR, ROOT, assert_ranks_agree, assert_refused, read_history,
                         replace, scene_on_every_rank)

from impact_fenics import cli, meshing
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.errors import InputError
from impact_fenics.materials import LinearElastic
from impact_fenics.probes import Probes
from impact_fenics.quad_meshes import quad_rectangle
from impact_fenics.simulation import Simulation

COMM = MPI.COMM_WORLD
serial_only = pytest.mark.skipif(COMM.size > 1, reason="launches processes: serial only")
E, RHO = 200e9, 7850.0
# round-offs of one entry of c (the element's quadrature and the action's sums over the
# few cells at a node): as a row of K, at most 64 on numbers of the size of the terms
C_ROUNDINGS = 64


def read_probes(probes: Probes, u_owned: np.ndarray) -> np.ndarray:
    """The probes' values at the owned displacement ``u_owned`` (m): one raw row recorded,
    summed over the ranks, evaluated."""
    block = np.zeros(probes.n_raw)
    probes.recorder(u_owned, block)(0)
    COMM.Allreduce(MPI.IN_PLACE, block, op=MPI.SUM)
    return probes.values(block[None, :])[0], block


def terms_scale(probes: Probes, block: np.ndarray) -> list[float]:
    """sum_j |c_j u_j| of each section (N): the scale of its dot product's roundings."""
    return [float(np.abs(c) @ np.abs(block[start: start + c.size]))
            for _, start, c in probes._sections]


# ------------------------------------------------------------------ a linear field
MESHES = {
    # a structured triangle bar r <= 0.05, 0 <= z <= 0.3, h = 1 cm: node rows every 1 cm
    "p1": (lambda: meshing.bar(radius=0.05, length=0.3, h=0.01, comm=COMM), "bar", 0.05,
           (0.1, 0.2, 0.29)),
    # rectangles 0.01 x 0.03 m, r in [0, 0.04], z in [0.1, 0.25]
    "q1": (lambda: quad_rectangle(COMM, 0.0, 0.1, 0.04, 0.25, 4, 5, "body"), "body", 0.04,
           (0.13, 0.16, 0.22)),
}


@pytest.mark.parametrize("kind", sorted(MESHES))
def test_section_carries_a_uniform_stress_exactly(kind):
    make, body, radius, heights = MESHES[kind]
    material = LinearElastic(E=E, nu=0.3, density=RHO)
    model = DeformableModel(make(), [Body(body, material)])
    a, b = -1e-3, 2e-4  # u_z = a z, u_r = b r: a uniform compression
    xy = model.node_xy[: model.n_owned // 2]
    u_owned = np.column_stack([b * xy[:, 0], a * xy[:, 1]]).ravel()
    probes = Probes(model, [(f"s{k}", (0.0, z), "section") for k, z in enumerate(heights)])
    got, block = read_probes(probes, u_owned)
    sigma_zz = material.lmbda * (2 * b + a) + 2 * material.mu * a
    exact = -sigma_zz * np.pi * radius ** 2
    # c's entries and the dot product's terms: C_ROUNDINGS + n roundings of sum |c_j u_j|
    bound = [rounding(C_ROUNDINGS + c.size, s) + rounding(4, abs(exact))
             for (_, _, c), s in zip(probes._sections, terms_scale(probes, block))]
    if COMM.rank == 0:
        print(f"{kind} uniform stress: F_s - (-sigma_zz pi R^2) = {(got - exact).tolist()} N "
              f"of {exact:.6e} N; bounds {bound}")
    assert exact > 0.0
    assert np.all(np.abs(got - exact) <= bound)


def test_probes_refuse_bad_sections():
    """The Python path: a plane between node rows, outside the body, at its end (or at
    the interface of two bodies), through a path-dependent or a finite-strain body; each
    an InputError naming the section."""
    from impact_fenics.materials import J2

    tm = meshing.coaxial_bars(radius=0.02, striker_length=0.04, target_length=0.04, h=0.01,
                              structured=True, comm=COMM)
    steel = LinearElastic(E=E, nu=0.3, density=RHO)
    model = DeformableModel(tm, [Body("striker", steel), Body("target", steel)])
    for z, words in ((0.015, "cuts cells of body 'target'"), (0.05, "passes through no body"),
                     (0.04, "passes through no body"), (0.0, "passes through no body")):
        with pytest.raises(InputError, match=f"probe 's': the plane z = {z!r} m " + words):
            Probes(model, [("s", (0.0, z), "section")])
    j2 = J2(E=E, nu=0.3, density=RHO, yield_stress=300e6)
    model = DeformableModel(tm, [Body("striker", steel), Body("target", j2)])
    with pytest.raises(InputError, match="probe 's': body 'target' is not linear elastic"):
        Probes(model, [("s", (0.0, 0.02), "section")])
    # a finite-strain body (a Q1 mesh): refused the same way
    from impact_fenics.materials import NeoHookean

    model = DeformableModel(quad_rectangle(COMM, 0.0, 0.1, 0.04, 0.25, 4, 5, "body"),
                            [Body("body", NeoHookean(E=E, nu=0.3, density=RHO))])
    with pytest.raises(InputError, match="probe 's': body 'body' is not linear elastic"):
        Probes(model, [("s", (0.0, 0.16), "section")])


# ------------------------------------------------------------------ momentum, struck bars
V0, LENGTH = 5.0, 0.4  # m/s, m: the lower half thrown at the upper half


def part_momentum(sim, z: float) -> float:
    """z momentum (kg m/s) of the nodes at z >= ``z`` (the plane's nodes included)."""
    integ, model = sim.integrator, sim.model
    zn = model.node_xy[: model.n_owned // 2, 1]
    above = np.repeat(zn >= z - 1e-10 * model.length_scale, 2)
    above[0::2] = False
    return COMM.allreduce(float(integ.mass[above] @ integ.v_owned[above]))


def momentum_bound(sim, n_steps: int, v_max: float) -> float:
    """Round-off of the momentum identity over ``n_steps`` steps (kg m/s). Step n rounds
    each dof's update v += A u (a row of 18 terms, A = -h M^-1 K with its own roundings:
    24 in all) on sum_j |A_ij u_j|, which is h |K|_i |u| / m_i with |u| <= v_max n h: the
    stable step's h^2 omega^2 <= 4 makes h |K|_i / m_i of order 4 / h (the absolute row
    sum exceeds omega^2 by the few cells at a node: a factor 4 kept), so 16 v_max n per
    unit mass; the rows of K above the plane cancel their sum only to C_ROUNDINGS of the
    same terms, and the step's F_s = c . u rounds as many (c a row of K's size). Summed
    over n = 1 .. N: (24 + 2 x 64) x 16 N^2 / 2 of M v_max, M the body's mass; the two
    momentum sums a rounding a dof of M v_max."""
    mass = sum(sim.body_mass.values())
    n = (24 + 2 * C_ROUNDINGS) * 8 * n_steps ** 2 + 2 * sim.model.n_global
    return rounding(n, mass * v_max)


def struck_mesh(kind: str):
    """The struck bar's mesh: triangles (``p1``) or quadrilaterals (``q1``), h = 1.25 cm."""
    from impact_fenics.quad_meshes import quad_bar
    from impact_fenics.quad_meshes import tag_rectangle

    return (meshing.bar(radius=0.05, length=LENGTH, h=0.0125, structured=True, comm=COMM)
            if kind == "p1" else tag_rectangle(quad_bar(COMM, 0.05, LENGTH, 4, 32), "bar"))


def struck_bar(kind: str, out, compiled: bool, heights, tm=None) -> Simulation:
    """The bar, its lower half moving up at V0, with a section at each of ``heights``; on
    the mesh ``tm`` if given (runs compared bit for bit share one: two partitions of the
    same mesh need not be equal)."""
    from test_step_block import _settings

    tm = struck_mesh(kind) if tm is None else tm
    model = DeformableModel(tm, [Body("bar", LinearElastic(E=E, nu=0.3, density=RHO))])
    sim = Simulation(model, _settings(out, compiled, n_steps=160, output_every=40))
    zn = model.node_xy[: model.n_owned // 2, 1]
    v0 = np.zeros(model.n_owned)
    v0[1::2] = np.where(zn < 0.5 * LENGTH, V0, 0.0)  # the lower half moves up
    sim.integrator.set_initial(None, v0)
    for k, z in enumerate(heights):
        sim.add_probe(f"section_{k}", (0.0, z), "section")
    return sim


HEIGHTS = (0.25, 0.3, 0.35)  # node rows of both meshes (h = 1.25 cm)


@pytest.mark.parametrize("kind", ["p1", "q1"])
def test_section_impulse_is_the_momentum_beyond_it(kind, tmp_path_factory):
    """The compiled steps and the Python steps write the same (bit for bit); the impulse
    through each section equals the change of momentum above it."""
    from test_step_block import _same

    sims = {}
    tm = struck_mesh(kind)

    def make(out, compiled):
        sims[compiled] = struck_bar(kind, out, compiled, HEIGHTS, tm)
        sims[compiled]._p0 = [part_momentum(sims[compiled], z) for z in HEIGHTS]
        return sims[compiled]
    got = _same(make, tmp_path_factory, f"section_{kind}", expect_contact=False)
    sim = sims[True]
    h, n = sim.settings.dt, sim.n_steps
    # rows hold u^1 .. u^n; F_s(u^0) = 0 (at rest undeformed): the steps' forces are
    # F_s(u^0 .. u^{n-1}), all rows but the last
    # the discrete wave overshoots the particle speed by less than V0: speeds below 2 V0
    bound = momentum_bound(sim, n, 2 * V0)
    for k, z in enumerate(HEIGHTS):
        force = got[f"history.section_{k}"]
        assert len(force) == n and np.max(force) > 0.0  # the wave reached it, compressive
        impulse = h * float(np.sum(force[:-1]))
        change = part_momentum(sim, z) - sim._p0[k]
        if COMM.rank == 0:
            print(f"{kind} struck bar, section z = {z}: impulse {impulse:.15e} N s, momentum "
                  f"change {change:.15e} kg m/s, difference {impulse - change:.3g} "
                  f"(bound {bound:.3g})")
        assert abs(impulse - change) <= bound


# ------------------------------------------------------------------ the nu = 0 wave
P0, T_RISE, RADIUS, STATIONS = WAVE_PEAK, WAVE_RISE, WAVE_RADIUS, WAVE_STATIONS


@pytest.mark.parametrize("h", [0.01, 0.005])
def test_section_reads_p_A_in_the_plateau(wave_bars, h):
    sim = wave_bars[h]
    material = next(iter(sim.model.bodies.values())).material
    c0 = material.bar_wave_speed()
    hist = sim.history.data()
    t = hist["time"]
    exact = P0 * np.pi * RADIUS ** 2  # N, compression positive
    for k, z in enumerate(STATIONS):
        force = hist[f"section_{k}"]
        plateau, arrival = wave_plateau(t, force, exact)
        late = abs(arrival - (z / c0 + T_RISE / 2))
        if COMM.rank == 0:
            print(f"h = {h} m, section at z = {z} m: plateau {plateau:.6e} N vs p A = "
                  f"{exact:.6e} N (rel. error {abs(plateau / exact - 1):.2e}, bound "
                  f"{(h / 0.1) ** 2:.2e}); arrival error {late:.3e} s, bound "
                  f"{h / c0 + sim.settings.dt:.3e} s")
        assert abs(plateau - exact) <= (h / 0.1) ** 2 * exact
        assert late <= h / c0 + sim.settings.dt  # the mesh's spread and the sampling


@pytest.mark.parametrize("h", [0.01, 0.005])
def test_section_impulse_under_a_load_below(wave_bars, h):
    """The Python steps (a surface load acts): the load is below every section and the
    far end is free, so the impulse through a section is the change of momentum above it
    (the bar starts at rest: that momentum itself)."""
    sim = wave_bars[h]
    hist = sim.history.data()
    # the particle speed p / (rho c0), doubled where the front meets the free end, and
    # the discrete front's overshoot below another factor 2
    v_max = P0 / (RHO * sim.model.bodies["bar"].material.bar_wave_speed())
    bound = momentum_bound(sim, sim.n_steps, 4 * v_max)
    for k, z in enumerate(STATIONS):
        impulse = sim.settings.dt * float(np.sum(hist[f"section_{k}"][:-1]))
        change = part_momentum(sim, z)
        if COMM.rank == 0:
            print(f"h = {h} m, section z = {z}: impulse {impulse:.15e} N s, momentum above "
                  f"{change:.15e} kg m/s, difference {impulse - change:.3g} (bound {bound:.3g})")
        assert impulse > 0.0
        assert abs(impulse - change) <= bound


# ------------------------------------------------------------------ the scene file
with open(os.path.join(ROOT, "scenes", "elastic_wave.toml")) as f:
    WAVE = f.read()
SCENE = replace(replace(WAVE, "h = 0.005 ", "h = 0.01  "), "t_end = 1.5e-4", "t_end = 1e-4") + """
[[probes]]
name = "section_0"
z = 0.3
quantity = "section"

[[probes]]
name = "section_1"
z = 0.45
quantity = "section"
"""


def test_scene_section_runs_and_reads_the_same_on_1_2_3_ranks(tmp_path_factory):
    """The scene through the CLI in this process (its history holds the section columns,
    near p A behind the front); in the serial pass also on 2 and 3 ranks, launched: every
    value within 1e-10 of the column's largest (the partitions reorder the sums that make
    c and each step: round-off, which the undamped wave does not amplify beyond it)."""
    base, scene = scene_on_every_rank(tmp_path_factory, "section_scene", SCENE)
    out = os.path.join(base, "n1")
    assert cli.main(["run", scene, "--out", out, "--quiet"]) == 0
    h1 = read_history(out)
    assert np.max(h1["section_0"]) > 0.9 * P0 * np.pi * RADIUS ** 2  # the pulse passed it
    if COMM.size > 1:
        return
    assert_ranks_agree(scene, base, h1, ("section_0", "section_1"), "N")


BAD = [
    ("z = 0.45\n", "z = 0.455\n",
     "error: [probes #6] the plane z = 0.455 m cuts cells of body 'bar': a section is a row"),
    ("z = 0.45\n", "z = 1.5\n", "error: [probes #6] the plane z = 1.5 m passes through no body"),
    ("z = 0.45\n", "z = 1.0\n", "error: [probes #6] the plane z = 1.0 m passes through no body"),
    ("z = 0.45\n", "point = [0.0, 0.45]\n",
     'error: [probes #6] point = [0.0, 0.45]: a quantity = "section" is the plane z = const'),
]


@serial_only
@pytest.mark.parametrize("edit", BAD, ids=["between_rows", "outside", "end_face", "point"])
def test_bad_sections_are_refused_in_one_line(tmp_path, edit):
    scene = tmp_path / "scene.toml"
    scene.write_text(replace(SCENE, edit[0], edit[1]))
    _refused(scene, tmp_path, edit[2])


@serial_only
def test_a_section_through_a_path_dependent_body_is_refused(tmp_path):
    """The tiny two-bar scene with a j2 target: a section through it is refused."""
    scene = tmp_path / "scene.toml"
    text = replace(PAIR, '[bodies.target]\nmaterial = "steel"',
                   '[materials.soft]\nmodel = "j2"\nE = 200e9\nnu = 0.3\ndensity = 7850.0\n'
                   'yield_stress = 300e6\n\n[bodies.target]\nmaterial = "soft"')
    scene.write_text(text + '\n[[probes]]\nname = "section"\nz = 0.02\nquantity = "section"\n')
    _refused(scene, tmp_path, "error: [probes #2] body 'target' is not linear elastic")


def _refused(scene, tmp_path, expected: str) -> None:
    out = tmp_path / "out"
    assert_refused(["run", str(scene), "--quiet", "--out", str(out)], expected, out)
