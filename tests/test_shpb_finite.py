"""The split Hopkinson pressure bar with a finite-strain J2 specimen (scenes/shpb_finite.toml,
docs/shpb.md "A finite-strain specimen").

Every body is Q1 ([mesh] quadrilaterals = true): the striker and the bars linear elastic at
small strain, the specimen J2 at finite strain (multiplicative, Hencky elasticity, the
yield on the Kirchhoff stress tau). A uniform specimen of length L carries
tau = F L / (A_0 L_0) whatever its J (A = J A_0 L_0 / L), so the analysis compares each
curve's engineering stress F / A_0 with tau(e) / (1 - eps), tau(e) the law at the log
strain e = -ln(1 - eps) (shpb/run_analysis.material_law); the Cauchy stress tau / J
differs from tau by J - 1 = (1 - 2 nu) tau / E, 0.07 % at 350 MPa.

Suite (a shrunk scene: 10 mm bars, a 50 mm striker, flat pulse; the specimen of the
shipped scene's J2 steel, 5 mm x 2.5 mm on 10 x 10 cells, a quarter of the bars' area so
that it yields; 4027 steps of 2^-26 s):

* the ledger: energy.csv's balance within roundoff.ledger at every row (the kinetic
  identity of the half-step scheme, exact for the linear bars, the finite specimen and
  the three contacts);
* z momentum: no external force acts along z (only the axis' u_r is held), so it stays
  m_striker v0 within the same bound;
* the run goes through `impact-fenics run` (which ends with the analysis) and again
  through `impact-fenics shpb`, with and without `--dispersion`; shpb.csv's law is the
  finite one, tau(e) / (1 - eps), at the 3-wave strain (to a few roundings: a log, a
  product and a quotient).

Study (`make study-shpb`, pytest -m study): the shipped scene, the oracle's bounds where
the gauges' R <= 5 % and the 3-wave rate is within 10 % of its median: the truth (the
faces' contact forces at the faces' displacement strain) within 1 % of the law point by
point, the 1-wave and the 3-wave stress within 2 % (on the bars the sizing rule gives:
docs/shpb.md); with the specimen's cells halved the 1-wave strain's offset from the
faces' stays (the 1-wave analysis' own, not the mesh's). The dispersion-corrected analysis, on
the shipped bars (the reflected wave's record cut: warned) and with a longer incident
bar (its record whole): there the corrected 3-wave stress within 2 % and the corrected
face forces nearer the faces' contact forces than the uncorrected. The same scene with an OFHC copper
Johnson-Cook specimen: the truth within
3 % of its flow stress at the run's strain rate and the specimen's volume-mean
temperature (adiabatic heating from its plastic work), point by point on the plateau.
"""
import json
import math
import os

import numpy as np
import pytest
from mpi4py import MPI

from roundoff import LIBM, ledger, rounding
from scene_texts import ROOT, replace, scene_on_every_rank

COMM = MPI.COMM_WORLD
E_S, SIGMA_Y, H = 200e9, 300e6, 1e9  # Pa: the specimen's J2 steel (scenes/shpb_finite.toml)
V = 10.0  # m/s, the striker


def _short_scene() -> str:
    with open(os.path.join(ROOT, "scenes", "shpb_finite.toml")) as f:
        text = f.read()
    for old, new in (("bar_diameter = 0.02 ", "bar_diameter = 0.01 "),
                     ("striker_length = 0.2 ", "striker_length = 0.05 "),
                     ("incident_length = 0.85 ", "incident_length = 0.12 "),
                     ("transmitter_length = 0.48 ", "transmitter_length = 0.07 "),
                     ("specimen_diameter = 0.01 ", "specimen_diameter = 0.005 "),
                     ("specimen_length = 0.005 ", "specimen_length = 0.0025 "),
                     ('method = "penalty"\npenalty = 2.8e7 ', 'method = "dme" '),
                     ("t_end = 4.2000412940979004e-4 ", "t_end = 6.000697612762451e-05 "),
                     ("z = 0.425 ", "z = 0.06 "), ("z = 0.905 ", "z = 0.145 "),
                     ("point = [0.0, 0.85025]", "point = [0.0, 0.12025]"),
                     ("point = [0.0, 0.85475]", "point = [0.0, 0.12225]"),
                     ("output_every = 400", "fields = false\nenergy_every = 1")):
        text = replace(text, old, new)
    return text


@pytest.fixture(scope="module")
def short_run(tmp_path_factory):
    """The shrunk run's directory (the run ends with the analysis)."""
    from impact_fenics import cli

    assert 4027 * 2.0 ** -26 == 6.000697612762451e-05  # t_end a whole number of steps
    base, scene = scene_on_every_rank(tmp_path_factory, "shpb_finite_short", _short_scene())
    out = os.path.join(base, "run")
    assert cli.main(["run", scene, "--out", out, "--quiet"]) == 0
    COMM.barrier()
    return out


def test_the_ledger_and_momentum(short_run):
    with open(os.path.join(short_run, "summary.json")) as f:
        s = json.load(f)
    assert s["status"] == "completed" and s["n_steps"] == 4027
    assert s["bodies"]["specimen"]["plastic_work"] > 0.0  # the specimen yields
    assert "plastic_work" not in s["bodies"]["incident"]  # the bars stay linear
    e = np.genfromtxt(os.path.join(short_run, "energy.csv"), delimiter=",", names=True)
    bound = ledger(s["n_steps"], s["n_dofs"])
    assert np.abs(e["balance_error"]).max() <= bound * e["total"][0]
    p0 = s["bodies"]["striker"]["mass"] * V  # N s: the striker's, the rest at rest
    assert abs(e["momentum_z"][0] / p0 - 1.0) <= rounding(4)
    assert np.abs(e["momentum_z"] - e["momentum_z"][0]).max() <= bound * p0


@pytest.mark.parametrize("options", [[], ["--dispersion"]])
def test_the_command_analyses_the_finite_specimen(short_run, options):
    """With and without the dispersion correction (the finite run's waves moved between
    gauge and face like any run's): the law beside the curves is the finite one at the
    analysis' own 3-wave strain."""
    from impact_fenics import cli

    assert cli.main(["shpb", short_run] + options) == 0
    COMM.barrier()
    d = np.genfromtxt(os.path.join(short_run, "shpb.csv"), delimiter=",", names=True)
    eps = d["strain_3"]
    loading = eps > 0.0
    log = -np.log1p(-eps[loading])
    tau = np.minimum(E_S * log, (SIGMA_Y + H * log) * E_S / (E_S + H))
    law = tau / (1.0 - eps[loading])
    # a log, the minimum's products and sums, the quotient: a few roundings of the law
    assert np.abs(d["stress_law_3"][loading] - law).max() <= rounding(LIBM + 8, law.max())
    assert np.max(d["stress_true"]) > SIGMA_Y  # the specimen reached its yield
    assert math.isfinite(float(np.nanmax(d["equilibrium_ratio"])))


# a longer incident bar (docs/shpb.md, "The dispersion-corrected curve"): the gauge
# 0.55 m from the struck end and from the specimen, so the record runs on past the
# reflected wave (at the gauge from 327 us, 167 us long) and ends before its reflection
# from the struck end returns (545 us): 36239 steps of 2^-26 s (540 us); the transmitter
# 0.6 m
LONGER_T_END = 36239 * 2.0 ** -26
LONGER = (("incident_length = 0.85 ", "incident_length = 1.1 "),
          ("transmitter_length = 0.48 ", "transmitter_length = 0.6 "),
          ("t_end = 4.2000412940979004e-4 ", f"t_end = {LONGER_T_END!r} "),
          ("z = 0.425 ", "z = 0.55 "), ("z = 0.905 ", "z = 1.155 "),
          ("point = [0.0, 0.85025]", "point = [0.0, 1.10025]"),
          ("point = [0.0, 0.85475]", "point = [0.0, 1.10475]"))


def _finite_run(tmp_path_factory, specimen_halved: bool = False, longer: bool = False) -> str:
    """scenes/shpb_finite.toml run to the end (no fields); with ``specimen_halved`` the
    specimen's cells halved (0.125 mm, 40 x 40), dt halved with them (2^-27 s, the same
    t_end: 38924 steps) and its face probes one (finer) cell row inside; the bars kept.
    With ``longer`` the incident bar of LONGER (its reflected wave passes its gauge)."""
    from impact_fenics import cli

    with open(os.path.join(ROOT, "scenes", "shpb_finite.toml")) as f:
        text = replace(f.read(), "output_every = 400", "fields = false")
    if specimen_halved:
        for old, new in (("h_specimen = 0.00025 ", "h_specimen = 0.000125 "),
                         ("dt = 1.4901161193847656e-08 ", f"dt = {2.0 ** -27!r} "),
                         ("point = [0.0, 0.85025]", "point = [0.0, 0.850125]"),
                         ("point = [0.0, 0.85475]", "point = [0.0, 0.854875]")):
            text = replace(text, old, new)
    if longer:
        for old, new in LONGER:
            text = replace(text, old, new)
    name = ("shpb_finite_specimen_halved" if specimen_halved else
            "shpb_finite_longer" if longer else "shpb_finite")
    base, scene = scene_on_every_rank(tmp_path_factory, name, text)
    out = os.path.join(base, "run")
    assert cli.main(["run", scene, "--out", out, "--quiet"]) == 0
    COMM.barrier()
    return out


@pytest.fixture(scope="module")
def finite_shipped(tmp_path_factory):
    return _finite_run(tmp_path_factory)


@pytest.mark.study
def test_the_recovered_curve_of_the_finite_specimen(finite_shipped):
    """The shipped scenes/shpb_finite.toml: the truth within 1 % of the finite law, the
    1-wave and the 3-wave stress within 2 %, point by point on the plateau."""
    from impact_fenics.shpb.run_analysis import analyse_run
    from test_shpb_study import errors

    r = analyse_run(finite_shipped)
    e = errors(r)
    if COMM.rank == 0:
        print("finite specimen", {k: (f"{np.mean(v):+.4f}", f"{np.max(np.abs(v)):.4f}")
                                  for k, v in e.items() if k not in ("transits", "window")},
              f"rate {r.rate:.4g} 1/s, equilibrium after {e['transits']:.3g} transits")
    assert np.max(np.abs(e["truth"])) <= 0.01
    assert np.max(np.abs(e["1-wave"])) <= 0.02
    assert np.max(np.abs(e["3-wave"])) <= 0.02
    assert math.isfinite(e["transits"])


def one_wave_lag(run_dir: str) -> tuple[float, float]:
    """On the plateau: the mean 1-wave strain less the faces' (-), and the mean error of
    the 1-wave stress against the law read at the faces' strain (-)."""
    from impact_fenics.shpb.run_analysis import analyse_run, columns, material_law

    r = analyse_run(run_dir)
    c, p = columns(r), r.plateau
    law = material_law(r.setup.specimen_material, c["strain_true"][p], r.rate)
    return (float(np.mean(c["strain_1"][p] - c["strain_true"][p])),
            float(np.mean(c["stress_1"][p] / law - 1.0)))


def all_errors(run_dir: str, dispersion: bool) -> dict[str, np.ndarray]:
    """The errors of test_shpb_study.errors on the run's plateau (with or without the
    dispersion correction: each analysis on its own plateau), with the 2-wave stress's
    (at the 3-wave strain), and each face force of the gauges against the faces' contact
    force over the mean of the two ('front', 'back'), the waves' own error at the faces."""
    from impact_fenics.shpb.run_analysis import analyse_run, columns, material_law
    from test_shpb_study import errors

    r = analyse_run(run_dir, dispersion)
    e = errors(r)
    c, p = columns(r), r.plateau
    e["2-wave"] = c["stress_2"][p] / material_law(r.setup.specimen_material,
                                                  c["strain_3"][p], r.rate) - 1.0
    mean = 0.5 * (c["force_front_true"][p] + c["force_back_true"][p])
    e["front"] = (c["force_front"][p] - c["force_front_true"][p]) / mean
    e["back"] = (c["force_back"][p] - c["force_back_true"][p]) / mean
    e["cut"] = r.waves.cut
    return e


def _print_errors(label: str, e: dict) -> None:
    if COMM.rank == 0:
        print(label, {k: (f"{np.mean(v):+.4f}", f"{np.max(np.abs(v)):.4f}")
                      for k, v in e.items() if k not in ("transits", "cut", "window")},
              f"{int(e['truth'].size)} plateau samples, cut {e['cut']}")


@pytest.fixture(scope="module")
def finite_longer(tmp_path_factory):
    return _finite_run(tmp_path_factory, longer=True)


@pytest.mark.study
def test_the_dispersion_corrected_curve_of_the_finite_specimen(finite_shipped, finite_longer):
    """The finite specimen's 1-, 2- and 3-wave stresses with and without the dispersion
    correction, on the shipped scene (whose incident record ends before the reflected
    wave has passed: the correction is warned as cut) and with the longer incident bar
    (LONGER: the record runs on past the reflected wave). On the longer bar the corrected
    3-wave stress is held to the page's 2 % point by point, and the correction brings
    the gauges' face forces nearer the faces' contact forces than the shift by c0 does."""
    shipped = all_errors(finite_shipped, dispersion=True)
    _print_errors("finite, shipped, corrected:", shipped)
    assert shipped["cut"] == ("reflected",)  # warned: the record ends inside the wave
    plain = all_errors(finite_longer, dispersion=False)
    corrected = all_errors(finite_longer, dispersion=True)
    _print_errors("finite, longer incident bar, uncorrected:", plain)
    _print_errors("finite, longer incident bar, corrected:", corrected)
    assert corrected["cut"] == ()
    assert np.max(np.abs(corrected["truth"])) <= 0.01
    assert np.max(np.abs(corrected["3-wave"])) <= 0.02
    for face in ("front", "back"):
        assert np.max(np.abs(corrected[face])) < np.max(np.abs(plain[face]))


@pytest.mark.study
def test_the_one_wave_offset_is_the_analysis_not_the_mesh(finite_shipped, tmp_path_factory):
    """The finite specimen's 1-wave strain is offset from the faces' (+0.0028 on the
    rule's bars, docs/shpb.md). With the specimen's cells halved the offset stays: a
    discretisation error of first order or higher would at least halve, so it is held
    above 3/4 of the shipped mesh's (between no change and a halving). The 1-wave stress
    read at the faces' strain is on the law within the truth's 1 %."""
    from impact_fenics.shpb.run_analysis import analyse_run
    from test_shpb_study import errors

    halved = _finite_run(tmp_path_factory, specimen_halved=True)
    figures = {}
    for name, run_dir in (("shipped", finite_shipped), ("specimen halved", halved)):
        e = errors(analyse_run(run_dir))
        lag, stress_at_faces = one_wave_lag(run_dir)
        figures[name] = (lag, stress_at_faces)
        if COMM.rank == 0:
            print(f"finite specimen, {name}: 1-wave {np.max(np.abs(e['1-wave'])):.4f} "
                  f"({np.mean(e['1-wave']):+.4f}), its strain less the faces' {lag:+.5f}, "
                  f"its stress at the faces' strain {stress_at_faces:+.4f}; truth "
                  f"{np.max(np.abs(e['truth'])):.4f} ({np.mean(e['truth']):+.4f})")
        assert abs(stress_at_faces) <= 0.01
    lag_shipped, lag_halved = figures["shipped"][0], figures["specimen halved"][0]
    assert lag_halved / lag_shipped >= 0.75


# OFHC copper (Johnson & Cook 1983; scenes/taylor_johnson_cook.toml): Pa, -, 1/s, K, J/(kg K)
JC = dict(E=124e9, nu=0.34, density=8960.0, A=90e6, B=292e6, n=0.31, C=0.025, rate0=1.0,
          m=1.09, t_room=293.0, t_melt=1356.0, chi=0.9, c_p=383.0)


def _johnson_cook_scene() -> str:
    with open(os.path.join(ROOT, "scenes", "shpb_finite.toml")) as f:
        text = replace(f.read(), "output_every = 400", "fields = false\nenergy_every = 20")
    start = text.index("[materials.specimen_steel]")
    end = text.index("[bodies.striker]")
    table = "[materials.specimen_steel]\nmodel = \"johnson_cook\"\n" + "".join(
        f"{k} = {v!r}\n" for k, v in JC.items()) + "\n"
    return text[:start] + table + text[end:]


def johnson_cook_law(eps: np.ndarray, rate: float, temperature: np.ndarray) -> np.ndarray:
    """The engineering stress F / A_0 (Pa) of a uniform Johnson-Cook specimen in uniaxial
    stress at the engineering strain ``eps`` (compression positive), the strain rate
    ``rate`` (1/s, of the log strain) and the temperature (K): tau / (1 - eps) with tau
    the flow stress (A + B e_p^n)(1 + C ln(rate / rate0))(1 - T*^m) at the plastic log
    strain e_p = -ln(1 - eps) - tau / E (Hencky: the elastic log strain tau / E),
    solved by fixed-point iteration (a contraction where (d tau / d e_p) / E < 1: 0.4 at
    e_p = 1e-4, 0.01 at the plateau's 0.02 and beyond; 200 sweeps leave it converged)."""
    log = -np.log1p(-eps)
    t_star = np.clip((temperature - JC["t_room"]) / (JC["t_melt"] - JC["t_room"]), 0.0, 1.0)
    factor = (1.0 + JC["C"] * math.log(max(rate / JC["rate0"], 1.0))) * (1.0 - t_star ** JC["m"])
    tau = JC["A"] * factor
    for _ in range(200):
        e_p = np.maximum(log - tau / JC["E"], 0.0)
        tau = (JC["A"] + JC["B"] * e_p ** JC["n"]) * factor
    return tau / (1.0 - eps)


@pytest.mark.study
def test_the_johnson_cook_specimen(tmp_path_factory):
    """The shipped scene with an OFHC copper Johnson-Cook specimen: the truth within 3 % of
    its flow stress at the run's strain rate and the specimen's volume-mean temperature,
    T_room + chi W_p / (rho c_p V_0) (adiabatic: every point heats by chi dW_p / (rho c_p),
    W_p the specimen's plastic work of energy.csv, V_0 its volume), on the plateau."""
    from impact_fenics import cli
    from impact_fenics.shpb.run_analysis import analyse_run, columns

    base, scene = scene_on_every_rank(tmp_path_factory, "shpb_jc", _johnson_cook_scene())
    out = os.path.join(base, "run")
    assert cli.main(["run", scene, "--out", out, "--quiet"]) == 0
    COMM.barrier()
    r = analyse_run(out)
    c, p = columns(r), r.plateau
    assert p.sum() > 100
    e = np.genfromtxt(os.path.join(out, "energy.csv"), delimiter=",", names=True)
    volume = math.pi * 0.005 ** 2 * 0.005  # m^3, the specimen's (scenes/shpb_finite.toml)
    w_p = np.interp(c["time"][p], e["time"], e["plastic_work"])
    temperature = JC["t_room"] + JC["chi"] * w_p / (JC["density"] * JC["c_p"] * volume)
    eps = c["strain_true"][p]
    log_rate = r.rate / (1.0 - float(np.median(eps)))  # the log strain's, at the plateau
    law = johnson_cook_law(eps, log_rate, temperature)
    error = c["stress_true"][p] / law - 1.0
    if COMM.rank == 0:
        print(f"Johnson-Cook specimen: truth {np.mean(error):+.4f} (largest "
              f"{np.max(np.abs(error)):.4f}), rate {r.rate:.4g} 1/s, strain "
              f"{eps[0]:.4g} to {eps[-1]:.4g}, temperature {temperature[0]:.1f} to "
              f"{temperature[-1]:.1f} K, equilibrium after "
              f"{r.equilibrium_time(truth=True) / r.setup.transit:.3g} transits")
    assert np.max(np.abs(error)) <= 0.03
