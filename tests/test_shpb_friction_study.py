"""Friction at the specimen's faces of the SHPB (docs/shpb.md, "Friction").

Coulomb friction mu at both faces of the specimen (the bars' end faces) holds the faces'
radial expansion back: the specimen barrels and the mean pressure on its faces exceeds
the flow stress. The oracle of the rise is the slab (Siebel) estimate of a rigid-plastic
disc sliding at mu p everywhere on its faces, p/sigma_y = 2 (e^a - 1 - a)/a^2 with
a = 2 mu R/L, R the volume-equivalent radius (R^2 L = R0^2 L0) at the instant; it is an
estimate, indicative only beyond mu R/L ~ 0.1.

The study (`make study-shpb`, pytest -m study) runs scenes/shpb_shaped.toml with
mu = 0, 0.1 and 0.2 on both faces (DME, node to segment), twenty-one `r` probes on the
specimen's rim (its profile), and reads each run's truth (the faces' contact forces over
A_s at the strain of the faces' displacement probes) on the run's plateau (the gauges'
R <= 5 % and the 3-wave rate within 10 % of its median there) against the specimen's law.
It writes docs/figures/shpb_friction_curves.png, shpb_friction_profile.png and
shpb_friction.json. The suite runs one short friction scene end to end.
"""
import json
import os

import numpy as np
import pytest
from mpi4py import MPI

from roundoff import ledger
from scene_texts import ROOT, read_history, replace, scene_on_every_rank
from test_upsetting_study import slab

MUS = (0.0, 0.1, 0.2)
FRONT, L0, R0 = 0.85, 0.005, 0.005  # the shaped scene's front face z, specimen length, radius (m)
N_RIM = 21  # one r probe per node row of the rim (20 cells along the specimen)
NUDGE = 1e-7  # m: the probe points just inside the specimen (not on the faces' interface)
FIGURES = os.path.join(ROOT, "docs", "figures")


def with_friction(text: str, mu: float) -> str:
    """The scene ``text`` with ``friction = mu`` on its node-to-segment (dme) contacts at
    the specimen's two faces."""
    for face in ("incident_face", "transmitter_face"):
        old = f'master = "{face}"\nmethod = "dme"\n'
        text = replace(text, old, old + f"friction = {mu!r}\n")
    return text


def _rim_z() -> np.ndarray:
    z = FRONT + L0 * np.arange(N_RIM) / (N_RIM - 1)
    z[0] += NUDGE
    z[-1] -= NUDGE
    return z


def _scene(mu: float) -> str:
    with open(os.path.join(ROOT, "scenes", "shpb_shaped.toml")) as f:
        text = replace(f.read(), "output_every = 400", "fields = false")
    if mu > 0.0:
        text = with_friction(text, mu)
    probes = "".join(f'\n[[probes]]\nname = "rim_{k:02d}"\nquantity = "r"\n'
                     f"point = [{R0 - NUDGE!r}, {z!r}]\n" for k, z in enumerate(_rim_z()))
    return text + probes


def readings(out: str, mu: float) -> dict:
    """One run's figures: the truth's rise over the law on the plateau (mean of
    sigma/law - 1), the slab estimate's rise there (a with the volume-equivalent radius,
    and with R0/L0), mu R/L at the plateau's end, the rim profile at the end (m), the
    barrel (the rim radius at mid-height less the faces' mean, m), the slip work (J),
    the ledger's residual, and the curves."""
    from impact_fenics.shpb.run_analysis import analyse_run, columns, material_law
    from test_shpb_study import errors

    r = analyse_run(out)
    c, p = columns(r), r.plateau
    stress, strain = c["stress_true"], c["strain_true"]
    law = material_law(r.setup.specimen_material, strain, r.rate)
    length = L0 * (1.0 - strain[p])
    radius = R0 * np.sqrt(L0 / length)  # volume-equivalent: R^2 L = R0^2 L0
    a = 2.0 * mu * radius / length
    h = read_history(out)
    profile = np.array([h[f"rim_{k:02d}"][-1] for k in range(N_RIM)])
    mid = N_RIM // 2
    with open(os.path.join(out, "summary.json")) as f:
        summary = json.load(f)
    e = np.genfromtxt(os.path.join(out, "energy.csv"), delimiter=",", names=True)
    slip = sum(h[f"c{k}_slip_work"] for k in (1, 2)) if mu > 0.0 else np.zeros_like(h["time"])
    return {
        "mu": mu, "errors": errors(r),
        "rise": float(np.mean(stress[p] / law[p])) - 1.0,
        "slab": float(np.mean([slab(x) for x in a])) - 1.0,
        "slab_reference": slab(2.0 * mu * R0 / L0) - 1.0,
        "mu_R_over_L": float(mu * radius[-1] / length[-1]),
        "plateau_strain": (float(strain[p].min()), float(strain[p].max())),
        "rate": r.rate, "profile": profile,
        "barrel": float(profile[mid] - 0.5 * (profile[0] + profile[-1])),
        "slip_work": slip, "summary": summary,
        "ledger": float(np.max(np.abs(e["balance_error_rel"]))),
        "ledger_bound": ledger(summary["n_steps"], summary["n_dofs"]),
        "curve": (strain, stress, p), "law": law,
    }


def _figures(runs: list[dict]) -> None:
    """docs/figures/shpb_friction_curves.png (the truth against the strain per mu, the
    plateau bold, the law), shpb_friction_profile.png (the rim at the end) and
    shpb_friction.json (the table)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    os.makedirs(FIGURES, exist_ok=True)
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    for run, colour in zip(runs, ("k", "tab:blue", "tab:red")):
        strain, stress, p = run["curve"]
        ax.plot(strain, stress / 1e6, color=colour, lw=0.6, alpha=0.5)
        ax.plot(np.where(p, strain, np.nan), np.where(p, stress, np.nan) / 1e6, color=colour,
                lw=1.6, label=f"mu = {run['mu']:g}: rise {100 * run['rise']:+.2f} %")
    s, _, _ = runs[0]["curve"]
    order = np.argsort(s)
    ax.plot(s[order], runs[0]["law"][order] / 1e6, "g--", lw=1.0, label="J2 law")
    ax.set_xlim(0.0, 1.1 * max(float(np.max(r["curve"][0])) for r in runs))
    ax.set_ylim(0.0, None)
    ax.set_xlabel("strain (faces' displacement)")
    ax.set_ylabel("stress: faces' contact forces / A_s (MPa)")
    ax.set_title("SHPB, shaped pulse: friction at both faces (plateau bold)")
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(FIGURES, "shpb_friction_curves.png"), dpi=120)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(4.8, 4.4))
    height = (_rim_z() - FRONT) * 1e3
    for run, colour in zip(runs, ("k", "tab:blue", "tab:red")):
        ax.plot(run["profile"] * 1e3, height, "o-", color=colour, ms=3,
                label=f"mu = {run['mu']:g}: barrel {run['barrel'] * 1e6:.1f} um")
    ax.axvline(R0 * 1e3, color="0.6", lw=0.8, ls=":")
    ax.set_xlabel("rim radius at the end (mm)")
    ax.set_ylabel("height from the front face, reference (mm)")
    ax.set_title("specimen profile (R0 = 5 mm, L0 = 5 mm)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(FIGURES, "shpb_friction_profile.png"), dpi=120)
    plt.close(fig)

    table = [{k: run[k] for k in ("mu", "rise", "net", "slab", "slab_reference", "mu_R_over_L",
                                  "plateau_strain", "rate", "barrel", "ledger")}
             | {"fraction": run["net"] / run["slab"] if run["mu"] > 0 else None,
                "fraction_reference": (run["net"] / run["slab_reference"] if run["mu"] > 0
                                       else None),
                "slip_work": float(run["slip_work"][-1]),
                "profile": [float(x) for x in run["profile"]],
                "truth_mean": float(np.mean(run["errors"]["truth"])),
                "truth_max": float(np.max(np.abs(run["errors"]["truth"])))}
             for run in runs]
    with open(os.path.join(FIGURES, "shpb_friction.json"), "w") as f:
        json.dump(table, f, indent=1)


@pytest.mark.study
def test_friction_raises_the_flow_stress_and_barrels_the_specimen(tmp_path_factory):
    from impact_fenics import cli

    runs = []
    for mu in MUS:
        base, scene = scene_on_every_rank(tmp_path_factory, f"shpb_mu{mu:g}", _scene(mu))
        out = os.path.join(base, "run")
        assert cli.main(["run", scene, "--out", out, "--quiet"]) == 0
        MPI.COMM_WORLD.barrier()
        runs.append(readings(out, mu))
    free, low, high = runs
    free["net"] = 0.0
    for run in (low, high):  # net of the frictionless run's offset (mesh, dynamics)
        run["net"] = run["rise"] - free["rise"]
    if MPI.COMM_WORLD.rank == 0:
        _figures(runs)
        for run in runs:
            e = run["errors"]
            print(f"mu = {run['mu']:g}: rise {100 * run['rise']:+.3f} % (net "
                  f"{100 * run['net']:+.3f} %), slab "
                  f"{100 * run['slab']:+.3f} % (R0/L0: {100 * run['slab_reference']:+.3f} %), "
                  f"fraction {run['net'] / run['slab'] if run['mu'] else float('nan'):.3f} "
                  f"({run['net'] / run['slab_reference'] if run['mu'] else float('nan'):.3f}), "
                  f"mu R/L {run['mu_R_over_L']:.4f}, plateau strain {run['plateau_strain']}, "
                  f"rate {run['rate']:.1f} 1/s, barrel {run['barrel'] * 1e6:.2f} um, "
                  f"slip work {run['slip_work'][-1]:.4g} J, ledger {run['ledger']:.2e} "
                  f"(bound {run['ledger_bound']:.2e}); truth {np.mean(e['truth']):+.4f} "
                  f"({np.max(np.abs(e['truth'])):.4f}), 1-wave {np.mean(e['1-wave']):+.4f}, "
                  f"3-wave {np.mean(e['3-wave']):+.4f}")
    # mu = 0 is the frictionless shaped scene: the suite's oracles of its shipped mesh
    # (tests/test_shpb_study.py) hold on the same run
    assert abs(np.mean(free["errors"]["truth"])) <= 0.01
    assert abs(np.mean(free["errors"]["1-wave"])) <= 0.02
    assert abs(np.mean(free["errors"]["3-wave"])) <= 0.02
    # the rise is positive and grows with mu, and so does the barrel (at mu = 0 the faces
    # slide freely: no barrel beyond the radial inertia's)
    assert 0.0 < low["rise"] < high["rise"]
    assert free["barrel"] < low["barrel"] < high["barrel"] and low["barrel"] > 0.0
    for run in (low, high):
        # the ledger closes with the slip work booked in the contact work: the bound of an
        # identity summed over the run, EPS (32 steps + 4 dofs); the slip work never falls
        assert run["ledger"] <= run["ledger_bound"]
        assert run["slip_work"][-1] > 0.0 and np.all(np.diff(run["slip_work"]) >= 0.0)
    assert high["slip_work"][-1] > low["slip_work"][-1]
    # the slab estimate: at mu R/L ~ 0.1 (mu = 0.1; 0.109 at the plateau's end) the rise
    # net of the frictionless run's offset within the sum of (i) the slab's own error, 8.2 %
    # of its increment at a = 0.2 quasi-statically on the same L/D = 0.5 (full sliding at
    # mu p everywhere and a shear uniform through the height; docs/friction.md,
    # "Upsetting"), (ii) the spread of its two geometric readings, R_eq/L against R0/L0,
    # and (iii) the frictionless truth's offset from the law, which the subtraction removes
    # only up to the runs' different plateaus; beyond it (mu = 0.2) only the order
    bound = (0.082 + abs(low["slab"] - low["slab_reference"]) / low["slab"]
             + abs(free["rise"]) / low["slab"])
    assert abs(low["net"] / low["slab"] - 1.0) <= bound
    assert 0.5 <= high["net"] / high["slab"] <= 2.0


def _short_scene(mu: float) -> str:
    """scenes/shpb.toml shrunk (bars of 10 mm, a 50 mm striker: a 19.8 us pulse; 5 cells
    across the bars' radius) with a J2 specimen of 5 mm x 2.5 mm (it yields: four times
    the bars' stress on a quarter of their section) and ``mu`` at both faces."""
    with open(os.path.join(ROOT, "scenes", "shpb.toml")) as f:
        text = f.read()
    for old, new in (("bar_diameter = 0.02 ", "bar_diameter = 0.01 "),
                     ("striker_length = 0.2 ", "striker_length = 0.05 "),
                     ("incident_length = 0.5 ", "incident_length = 0.12 "),
                     ("transmitter_length = 0.25 ", "transmitter_length = 0.07 "),
                     ("specimen_diameter = 0.01 ", "specimen_diameter = 0.005 "),
                     ("specimen_length = 0.005 ", "specimen_length = 0.0025 "),
                     ("h_specimen = 0.00025 ", "h_specimen = 0.0005 "),
                     ("t_end = 2.4e-4 ", "t_end = 6e-5 "),
                     ("z = 0.25 ", "z = 0.06 "), ("z = 0.555 ", "z = 0.1425 "),
                     ("point = [0.0, 0.50025]", "point = [0.0, 0.1205]"),
                     ("point = [0.0, 0.50475]", "point = [0.0, 0.122]"),
                     ("output_every = 400", "fields = false")):
        text = replace(text, old, new)
    return with_friction(text, mu)


def test_a_short_friction_run_books_its_slip_work(tmp_path_factory):
    """A short SHPB run with mu = 0.2 at both faces runs end to end (the run, then the
    analysis again by the command): each face's slip work is positive, never falls, is
    the summary's, and the ledger closes within the bound of its identity."""
    from impact_fenics import cli

    base, scene = scene_on_every_rank(tmp_path_factory, "shpb_friction_short", _short_scene(0.2))
    out = os.path.join(base, "run")
    assert cli.main(["run", scene, "--out", out, "--quiet"]) == 0
    MPI.COMM_WORLD.barrier()
    assert cli.main(["shpb", out]) == 0
    MPI.COMM_WORLD.barrier()
    d = np.genfromtxt(os.path.join(out, "shpb.csv"), delimiter=",", names=True)
    assert np.all(np.isfinite(d["stress_true"])) and d["plateau"].sum() > 0
    h = read_history(out)
    with open(os.path.join(out, "summary.json")) as f:
        summary = json.load(f)
    for k, booked in zip((1, 2), summary["friction"]):
        slip = h[f"c{k}_slip_work"]
        assert slip[-1] > 0.0 and np.all(np.diff(slip) >= 0.0)
        assert booked["friction"] == "0.2" and booked["slip_work"] == slip[-1]
    e = np.genfromtxt(os.path.join(out, "energy.csv"), delimiter=",", names=True)
    # the ledger's identity summed over the run: EPS (32 steps + 4 dofs)
    assert np.max(np.abs(e["balance_error_rel"])) <= ledger(summary["n_steps"], summary["n_dofs"])
