"""A scene file that mixes kinematics: a linear elastic striker (small strain) onto a
finite-strain J2 target, both Q1 quadrilaterals on coaxial_bars_sized.

Scene: a steel striker (z in [-4R, 0], h = R/4) at v0 onto a copper target at rest
(z in [0, 4R], h = R/6), R = 3.2 mm; node to segment (the target's finer face the slave,
re-paired every 5 steps) under a fixed dt = 2^-24 s (a power of two, so t = n dt is
exact), or node pairs on matched faces (h = R/4 both) under
a step that follows the cells (cfl).

Oracles:

* the ledger: kinetic + strain + plastic + work_gap - contact work = E_0, the kinetic
  identity of the half-step scheme, exact for any forces (the linear body's K u, the
  finite body's total Lagrangian force and the contact's), within roundoff.ledger at
  every row of energy.csv;
* z momentum: nothing external acts (no dof held, no load), so it stays its initial value
  within the same bound (the contact forces G' lam are equal and opposite up to their
  roundings, the finite force's rows sum to zero up to theirs);
* 1, 2 and 3 ranks: the probes' u_z and the contact force of history.csv within 1e-10 of
  their largest value (the partitions reorder the sums of each step);
* low speed, nu = 0, elastic: the finite-strain target equals the same scene with a
  small-strain target (J2 on Q1, B-bar) to the order of the strain eps = v0 / c0 (c0
  the target's bar speed): Hencky's log strain against the linear one, the current
  against the reference configuration, change the stress by O(eps) relative, hence the
  wave speed; a front that has run c0 t arrives eps c0 t earlier or later, which over a
  cell h changes u and v by at most eps c0 t / h of their largest value. And the
  difference is first order: halving v0 halves it, within the same O(eps) factor
  (tests/test_two_finite_bodies.py states the same bound for two finite bodies).
* bad input: a held [wall] face off quad_bar and a finite-strain body on triangles are
  refused in one line, exit 2.

Every test runs unchanged on 1, 2 and 3 ranks (the compared arrays gathered).
"""
import json
import math
import os

import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics import cli
from impact_fenics.scene_file import build, read_scene
from roundoff import ledger
from scene_texts import COPPER_J2, FILM_SEGMENTS_100_STEPS, Q1_BARS_MESH, assert_ranks_agree, read_history, replace, scene_on_every_rank

COMM = MPI.COMM_WORLD
serial_only = pytest.mark.skipif(COMM.size > 1, reason="launches processes: serial only")
R = 3.2e-3  # m
E_CU, RHO_CU = 117e9, 8930.0  # Pa, kg/m^3: the copper target
C0 = math.sqrt(E_CU / RHO_CU)  # m/s, the target's bar speed
DT = 2.0 ** -24  # s (0.68 of the target's cells' limit at set-up)

MIXED = ("""
title = "a linear striker onto a finite-strain target"

"""
         + Q1_BARS_MESH
         + """
[materials.steel]
E = 200e9
nu = 0.3
density = 7850.0

"""
         + COPPER_J2
         + """
[bodies.striker]
material = "steel"
velocity = [0.0, 100.0]

[bodies.target]
material = "copper"
strain = "finite"

"""
         + FILM_SEGMENTS_100_STEPS
         + """
[output]
history_every = 1
energy_every = 1
fields = false
plots = false

[[probes]]
name = "target_foot"
quantity = "u_z"
point = [0.0, 0.8e-3]

[[probes]]
name = "striker_tail"
quantity = "u_z"
point = [0.0, -12.8e-3]
""")

# the same bodies on matched faces (h = R/4 both) in node pairs, the step following the cells
PAIRS = [("h_target = 5.333333333333333e-4", "h_target = 8e-4"),
         ('slave = "target_contact"\nmaster = "striker_contact"',
          'lower = "striker_contact"\nupper = "target_contact"'),
         ("repair_every = 5\n", ""),
         ("dt = 5.9604644775390625e-08     # s, 2^-24 (exact)", "cfl = 0.5")]


def _text(edits=()) -> str:
    text = MIXED
    for old, new in edits:
        text = replace(text, old, new)
    return text


def _run(tmp_path_factory, name, text):
    base, scene = scene_on_every_rank(tmp_path_factory, name, text)
    out = os.path.join(base, "n1")
    assert cli.main(["run", scene, "--out", out, "--quiet"]) == 0
    COMM.barrier()
    with open(os.path.join(out, "summary.json")) as f:
        summary = json.load(f)
    return base, scene, out, summary


def _ledger_and_momentum(out, summary):
    """energy.csv's balance and z momentum within roundoff.ledger at every row."""
    e = np.genfromtxt(os.path.join(out, "energy.csv"), delimiter=",", names=True)
    bound = ledger(summary["n_steps"], summary["n_dofs"])
    e0 = e["total"][0]
    assert np.abs(e["balance_error"]).max() <= bound * e0
    p = e["momentum_z"]
    assert np.abs(p - p[0]).max() <= bound * abs(p[0])
    assert e["plastic_work"][-1] > 0.1 * e0  # the target's foot yields at finite strain
    return e


@pytest.mark.parametrize("kind", ["segments", "pairs"])
def test_a_linear_striker_onto_a_finite_target(tmp_path_factory, kind):
    """100 m/s, 6 us (the waves cross each body about twice): the ledger and z momentum
    of energy.csv within roundoff.ledger; the striker stays elastic."""
    text = _text(PAIRS if kind == "pairs" else ())
    base, scene, out, s = _run(tmp_path_factory, f"mixed_{kind}", text)
    assert s["status"] == "completed"
    assert s["n_steps"] == (100 if kind == "segments" else s["n_steps"])
    _ledger_and_momentum(out, s)
    assert "plastic_work" not in s["bodies"]["striker"]  # linear elastic: no such column


# the striker small-strain J2 (a path-dependent body: its stored energy and plastic work
# come from its positions, f . du) and DME, whose positions jump off u^n + h v^{n+1/2}
J2_STRIKER_DME = [("E = 200e9\nnu = 0.3\ndensity = 7850.0\n",
                   'model = "j2"\nE = 200e9\nnu = 0.3\ndensity = 7850.0\n'
                   "yield_stress = 300e6\nhardening = 1e9\n"),
                  ('method = "film"', 'method = "dme"')]


@pytest.mark.parametrize("kind", ["segments", "pairs"])
def test_dme_jumps_with_a_plastic_striker_onto_a_finite_target(tmp_path_factory, kind):
    """A small-strain J2 striker onto the finite-strain target by DME: the jumps are work
    on the striker's dofs (its energy is its positions' trapezoid) and on none of the
    target's (its work is the kinetic identity's, which no jump enters), so the ledger
    closes within roundoff.ledger at every row (booked on every slot, it missed by 1.4e-4
    of E_0 in this scene, node pairs and segments alike)."""
    text = _text(J2_STRIKER_DME + (PAIRS if kind == "pairs" else []))
    base, scene, out, s = _run(tmp_path_factory, f"mixed_dme_{kind}", text)
    assert s["status"] == "completed"
    _ledger_and_momentum(out, s)
    assert s["bodies"]["striker"]["plastic_work"] > 0.0  # the striker yields too


@serial_only
def test_a_mixed_scene_on_1_2_and_3_ranks(tmp_path_factory):
    base, scene, out, s = _run(tmp_path_factory, "mixed_ranks", _text())
    serial = read_history(out)
    columns = [c for c in serial if c in ("target_foot", "striker_tail")
               or (c.startswith("contact") and c.endswith("force"))]
    assert "target_foot" in columns and len(columns) >= 3, sorted(serial)
    assert_ranks_agree(scene, base, serial, columns, "m or N")


def _state(tmp_path_factory, name, text, tmesh, monkeypatch):
    """(u, v) of every global dof (m, m/s) at t_end, on every rank, of the scene built from
    ``text`` through the scene reader and run without outputs, on ``tmesh`` (the runs
    compared dof by dof share one mesh: one partition, one numbering)."""
    from impact_fenics import meshing

    _, path = scene_on_every_rank(tmp_path_factory, name, text)
    monkeypatch.setattr(meshing, "coaxial_bars_sized", lambda **kwargs: tmesh)
    sim = build(read_scene(path), {"out": None, "quiet": True, "plots": False,
                                   "fields": False, "timers": False})
    sim.run()
    assert sim.status == "completed"
    e = sim.energy.data()
    assert not e["plastic_work"].any()  # elastic
    integ = sim.integrator
    return (np.concatenate(COMM.allgather(integ.u_owned.copy())),
            np.concatenate(COMM.allgather(integ.v_owned.copy())))


def test_low_speed_finite_target_equals_small_strain(tmp_path_factory, monkeypatch):
    """nu = 0, v0 = 1 and 0.5 m/s (stress below rho c0 v0 = 31 MPa, far below the 400 MPa
    yield), 100 steps: the finite target against the small-strain one within eps c0 t / h
    of the largest |u| and |v|, eps = v0 / c0, h the target's cell (the finer face);
    halving v0 halves the difference within the same factor."""
    n_steps, h = 100, R / 6
    amplification = C0 * n_steps * DT / h  # fronts' travel over a cell (about 40)
    from impact_fenics import meshing

    rel = {}
    tmesh = meshing.coaxial_bars_sized(radius=R, striker_length=4 * R, target_length=4 * R,
                                       h_striker=R / 4, h_target=R / 6, quadrilaterals=True,
                                       comm=COMM)
    for v0 in (1.0, 0.5):
        runs = {}
        for strain in ("finite", "small"):
            text = _text([("nu = 0.3\n", "nu = 0.0\n"), ("nu = 0.35\n", "nu = 0.0\n"),
                          ("velocity = [0.0, 100.0]", f"velocity = [0.0, {v0!r}]"),
                          ('strain = "finite"', f'strain = "{strain}"')])
            runs[strain] = _state(tmp_path_factory, f"low_{strain}", text, tmesh, monkeypatch)
        (uf, vf), (us, vs) = runs["finite"], runs["small"]
        eps = v0 / C0
        rel[v0] = (np.abs(uf - us).max() / np.abs(us).max(),
                   np.abs(vf - vs).max() / np.abs(vs).max())
        if COMM.rank == 0:
            print(f"v0 = {v0} m/s: |u_f - u_s| / |u| = {rel[v0][0]:.3g}, |v_f - v_s| / |v| = "
                  f"{rel[v0][1]:.3g}, bound eps c0 t / h = {eps * amplification:.3g}")
        assert 0.0 < rel[v0][0] <= eps * amplification
        assert 0.0 < rel[v0][1] <= eps * amplification
    eps = 1.0 / C0
    for k in (0, 1):  # first order in the strain: the remainder is O(eps) of it
        assert abs(rel[1.0][k] / rel[0.5][k] / 2.0 - 1.0) <= eps * amplification


@pytest.mark.parametrize("edits, message", [
    ([("[time]", '[wall]\nz = 0.0\nmethod = "film"\nface = "held"\n\n[time]')],
     '[wall] face = "held": it holds the face Z = 0 of the bar of generator = "quad_bar"'),
    ([("quadrilaterals = true\n", "")],
     '[mesh] generator = "coaxial_bars_sized": a finite-strain body needs generator = '
     '"quad_bar" or "rod_on_anvil", or quadrilaterals = true (coaxial_bars_sized, shpb, '
     'block), or a mesh file of quadrilaterals: finite strain needs quadrilaterals'),
], ids=["held face", "triangles"])
def test_the_mixed_scene_refuses(tmp_path_factory, capsys, edits, message):
    """Bad input: one line naming the table, exit 2, no traceback."""
    _, scene = scene_on_every_rank(tmp_path_factory, "mixed_bad", _text(edits))
    with pytest.raises(SystemExit) as stop:
        cli.main(["run", scene, "--out", os.path.join(os.path.dirname(scene), "out"),
                  "--quiet"])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    if COMM.rank == 0:
        lines = [ln for ln in err.splitlines() if ln.strip()]
        assert len(lines) == 1 and lines[0].startswith(f"error: {message}"), err
        assert "Traceback" not in err


# the target Johnson-Cook copper (a material with a temperature), fields written
JC_TARGET = [('model = "j2"\nE = 117e9\nnu = 0.35\ndensity = 8930.0\nyield_stress = 400e6\n'
              "hardening = 100e6\n",
              'model = "johnson_cook"\nE = 117e9\nnu = 0.35\ndensity = 8930.0\nA = 90e6\n'
              "B = 292e6\nn = 0.31\nC = 0.025\nrate0 = 1.0\nm = 1.09\nt_room = 293.0\n"
              "t_melt = 1356.0\nchi = 0.9\nc_p = 383.0\n"),
             ("fields = false", "fields = true\noutput_every = 50")]


def test_the_temperature_field_is_the_heated_bodys_alone(tmp_path_factory):
    """A Johnson-Cook target under an elastic striker: fields.xdmf's temperature is the
    target's (at least its room temperature, up to the last bits of a running sum: a
    point only heats, dT = chi dW_p / (rho c_p) >= 0) and NaN on the striker's cells,
    which have no temperature (not 0 K, which a picture would show as the coldest)."""
    from impact_fenics.plotting import read_xdmf

    base, scene, out, s = _run(tmp_path_factory, "mixed_jc", _text(JC_TARGET))
    assert s["status"] == "completed"
    data = read_xdmf(os.path.join(out, "fields.xdmf"))
    last = len(data.fields["temperature"].times) - 1
    temp = data.values("temperature", last)
    target = data.values("body_id", last) == 1  # bodies in order: striker 0, target 1
    assert target.any() and (~target).any()
    assert np.isnan(temp[~target]).all()
    t_room = 293.0  # K, the scene's
    assert np.isfinite(temp[target]).all()
    assert temp[target].min() >= t_room * (1.0 - 8 * np.finfo(float).eps * s["n_steps"])
    assert temp[target].max() > t_room  # the foot yields and heats
