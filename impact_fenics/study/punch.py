"""Study parts 1 and 2: the rigid punch (paper Section 3.1).

Part 1 runs Sim1/Sim2/Sim3 (R_z = 1, 3, 6 m) with FILM (fast exact and dense
solvers), DME and penalty (the paper's p = 6e9 N/m, the same value times 2 pi
for per-radian masses, both readings of "auto", and the stability-scaled p),
and records the punch penetration, the contact force and the contact CPU time
of every step.

Part 2 sweeps the penalty on each radius: a uniform p from 1e7 to 1e11 N/m and
a p scaled with the ring masses (p_i = c / S_ii, every pair at the same
beta_ii) whose coupled beta_max = p lambda_max(S) is set on either side of the
bound 4/3 derived in contact/penalty.py. If the paper's explanation (p too
small far from the axis) were the cause, the mass-scaled p would cure the
failure at any level; if the coupled bound is the cause, the failure sets in
where beta_max crosses 4/3, for every radius and either family.
"""
from __future__ import annotations

import math

import numpy as np

from .. import scenes
from ..contact import DME, FILM, Penalty
from .common import BETA_BOUND, TWO_PI, contact_cpu, coupling, flips, log, pyplot, rel_l2, run_recorded, settings


def methods(p_paper: float):
    """(key, label, factory) of every method of part 1."""
    return [
        ("film_fast", "FILM (fast exact)", lambda: FILM("fast")),
        ("film_dense", "FILM (dense)", lambda: FILM("dense")),
        ("dme", "DME", lambda: DME()),
        ("p_paper", f"penalty {p_paper:.3g}", lambda: Penalty(p_paper)),
        ("p_paper_2pi", f"penalty {p_paper:.3g}·2π", lambda: Penalty(p_paper * TWO_PI)),
        ("p_auto_moi", "penalty auto, mean(1/S_ii)", lambda: Penalty("auto", auto_reading="mean_of_inverse")),
        ("p_auto_iom", "penalty auto, 1/mean(S_ii)", lambda: Penalty("auto", auto_reading="inverse_of_mean")),
        ("p_scaled", "penalty scaled (β=1)", lambda: Penalty("scaled")),
    ]


TIMED = ("film_fast", "film_dense", "dme", "p_paper")


def run_punch(cfg: dict, method, radius: float, n_steps: int | None = None, dt: float | None = None,
              pulse: dict | None = None, block: dict | None = None, probes=(), **kw) -> dict:
    """One punch run, recorded (a diverging run does not raise); ``probes`` are
    (name, (r, z), quantity) added to the run."""
    p = cfg["punch"]
    kw.setdefault("energy_growth_limit", 1e30)
    s = settings(dt=dt or p["dt"], n_steps=n_steps or p["n_steps"], output_every=10, **kw)
    sim = scenes.punch_indentation(s, method, radius=radius, block=block or p["block"],
                                   **(pulse or p["pulse"]))
    for name, point, quantity in probes:
        sim.add_probe(name, point, quantity)
    c = sim.contacts[0]
    rec = run_recorded(sim)
    rec["n"] = c.n
    rec["d"] = c.s_diagonal().copy()
    rec["kappa"] = coupling(c)
    rec["info"] = dict(getattr(c.method, "info", {}))
    rec["dt"] = sim.settings.dt
    rec["dt_critical"] = sim.dt_critical
    rec["dt_converged"] = sim.dt_converged
    rec["n_cells"] = rec["summary"]["n_cells"]
    rec["n_dofs"] = rec["summary"]["n_dofs"]
    return rec


def metrics(rec: dict, ref: dict, pulse: dict) -> dict:
    """Errors of one run against FILM: punch_u and punch_force over the loaded window
    [0, t_end of the pulse], penetration there, flips of the active set while the load
    is held, and the energy the contact put in (J, > 0 is a gain)."""
    h, hr = rec["history"], ref["history"]
    window = (0.0, pulse["t_end"])
    t = h["time"]
    held = (t >= pulse["t_rise"]) & (t <= pulse["t_fall"])
    inside = t <= pulse["t_end"]
    e = rec["energy"]
    # energies relative to the work this run's load did (a soft spring lets the punch travel
    # further, so the load does more work: that is not a gain)
    own = e["external_work"][np.isfinite(e["external_work"])]
    ext = float(np.max(np.abs(own))) if own.size else 0.0
    ext = ext or float(np.nanmax(np.abs(ref["energy"]["external_work"]))) or 1.0
    gain = float(np.nanmax(e["contact_work"])) if e["contact_work"].size else 0.0
    pen = -np.minimum(h["min_gap"][inside], 0.0)
    return {
        "err_u": rel_l2(t, h["punch_u"], hr["time"], hr["punch_u"], window),
        "err_force": rel_l2(t, h["punch_force"], hr["time"], hr["punch_force"], window),
        "max_penetration": float(np.nanmax(pen)) if pen.size and np.all(np.isfinite(pen)) else float("inf"),
        "flips_hold": flips(h["n_active"][held]),
        "hold_steps": int(held.sum()),
        "contact_energy_gain_rel": gain / ext,
        "energy_max_rel": (float(np.nanmax(e["total"])) / ext if e["total"].size
                           and np.all(np.isfinite(e["total"])) else float("inf")),
        "status": rec["status"],
        "stopped_at": rec["stopped_at"],
    }


def classify(m: dict) -> str:
    """'diverged' (not finite, or 10 x the load's work), 'chatter' (the active set flips in
    more than 5 % of the steps while the load is held), 'energy gain' (the contact did
    positive work above 1 % of the load's) or 'stable'."""
    if m["status"] != "completed" or not m["energy_max_rel"] < 10.0:
        return "diverged"
    if m["flips_hold"] > 0.05 * max(m["hold_steps"], 1):
        return "chatter"
    if m["contact_energy_gain_rel"] > 0.01:
        return "energy gain"
    return "stable"


# ----------------------------------------------------------------------------- part 1

def paper_runs(cfg: dict, writer) -> dict:
    """Sim1/Sim2/Sim3 with every method; figures punch_sim{k}.png. Returns the results."""
    p = cfg["punch"]
    out = {"radii": {}, "dt": p["dt"], "n_steps": p["n_steps"], "pulse": p["pulse"],
           "timing_repeats": p["timing_repeats"]}
    plt = pyplot()
    for k, radius in enumerate(p["radii"], start=1):
        runs = {}
        for key, label, make in methods(p["p_paper"]):
            repeats = p["timing_repeats"] if key in TIMED else 1
            recs = [run_punch(cfg, make(), radius) for _ in range(repeats)]
            rec = recs[0]
            # per-step CPU: the minimum over repeats (the least disturbed estimate)
            for col in ("cpu_detection", "cpu_solve", "cpu_update"):
                rec["history"][col] = np.min([r["history"][col] for r in recs], axis=0)
            rec["wall"] = min(r["wall"] for r in recs)
            runs[key] = rec
        ref = runs["film_fast"]
        res = {"n_constraints": ref["n"], "methods": {}}
        for key, label, _ in methods(p["p_paper"]):
            rec = runs[key]
            h = rec["history"]
            cpu = contact_cpu(h)
            m = metrics(rec, ref, p["pulse"])
            m.update({
                "label": label,
                "state": classify(m),
                "beta_max": rec["info"].get("beta_max"),
                "p_min": rec["info"].get("p_min"), "p_max": rec["info"].get("p_max"),
                "contact_cpu_median": float(np.median(cpu)),
                "contact_cpu_mean": float(np.mean(cpu)),
                "solve_cpu_median": float(np.median(h["cpu_solve"])),
                "wall": rec["wall"],
                "punch_u_min": float(np.nanmin(h["punch_u"][h["time"] <= p["pulse"]["t_end"]])),
                "series": {"time": h["time"], "punch_u": h["punch_u"], "punch_force": h["punch_force"],
                           "n_active": h["n_active"], "cpu_total": cpu, "cpu_solve": h["cpu_solve"]},
            })
            res["methods"][key] = m
        f = res["methods"]
        res["p_auto_mean_of_inverse"] = runs["p_auto_moi"]["info"]["p_auto_mean_of_inverse"]
        res["p_auto_inverse_of_mean"] = runs["p_auto_moi"]["info"]["p_auto_inverse_of_mean"]
        res["speedup_dme_vs_film_dense"] = f["film_dense"]["contact_cpu_median"] / f["dme"]["contact_cpu_median"]
        res["speedup_dme_vs_film_fast"] = f["film_fast"]["contact_cpu_median"] / f["dme"]["contact_cpu_median"]
        res["speedup_penalty_vs_film_dense"] = (f["film_dense"]["contact_cpu_median"]
                                                / f["p_paper"]["contact_cpu_median"])
        res["dme_vs_penalty"] = f["p_paper"]["contact_cpu_median"] / f["dme"]["contact_cpu_median"]
        res["film_dense_solve_share"] = (f["film_dense"]["solve_cpu_median"]
                                         / f["film_dense"]["contact_cpu_median"])
        out["radii"][f"sim{k}"] = dict(res, radius=radius)
        log(f"  Sim{k} (R_z = {radius:g} m, {ref['n']} constraints): contact CPU per step (median) "
            + ", ".join(f"{key} {f[key]['contact_cpu_median'] * 1e6:.0f} us" for key in TIMED)
            + "; states " + ", ".join(f"{key} {f[key]['state']}" for key in f))
        fig = _figure(plt, res, radius, k, p)
        writer.figure(f"punch_sim{k}", fig)
        writer.json(f"punch_sim{k}", res)
    return out


def _figure(plt, res, radius, k, p):
    f = res["methods"]
    fig, ax = plt.subplots(1, 3, figsize=(16, 4.4))
    ref_u = np.asarray(f["film_fast"]["series"]["punch_u"])
    ylim_u = (1.8 * np.nanmin(ref_u) - 1e-5, max(2e-4, -0.8 * np.nanmin(ref_u)))
    style = {"film_fast": ("k", "-"), "film_dense": ("0.5", ":"), "dme": ("C0", "--"),
             "p_paper": ("C3", "-"), "p_paper_2pi": ("C1", "-"), "p_auto_moi": ("C4", "-."),
             "p_auto_iom": ("C5", "-."), "p_scaled": ("C2", "-")}
    for key, m in f.items():
        s = m["series"]
        t = np.asarray(s["time"]) * 1e6
        color, ls = style[key]
        tag = "" if m["state"] == "stable" else f" [{m['state']}]"
        ax[0].plot(t, np.asarray(s["punch_u"]) * 1e3, color=color, ls=ls, lw=1.2, label=m["label"] + tag)
        ax[1].plot(t, np.asarray(s["punch_force"]) / 1e6, color=color, ls=ls, lw=1.0)
    ax[0].set_ylim(ylim_u[0] * 1e3, ylim_u[1] * 1e3)
    fmax = np.nanmax(np.asarray(f["film_fast"]["series"]["punch_force"]))
    ax[1].set_ylim(-0.1 * fmax / 1e6, 1.6 * fmax / 1e6)
    ax[0].set(xlabel="t (µs)", ylabel="punch displacement u_p (mm)",
              title=f"(a) Sim{k}: R_z = {radius:g} m, {res['n_constraints']} constraints")
    ax[1].set(xlabel="t (µs)", ylabel="contact force F_punch (MN)", title="(b) contact force")
    ax[0].legend(fontsize=7, loc="lower left")
    for key, lab, color in (("film_dense", "FILM dense", "0.4"), ("film_fast", "FILM fast", "k"),
                            ("dme", "DME", "C0"), ("p_paper", f"penalty {p['p_paper']:.3g}", "C3")):
        s = f[key]["series"]
        n = np.arange(1, len(s["cpu_total"]) + 1)
        ax[2].semilogy(n, np.asarray(s["cpu_total"]) * 1e6, color=color, lw=0.8, label=f"{lab}: total")
        if key.startswith("film"):
            ax[2].semilogy(n, np.maximum(np.asarray(s["cpu_solve"]) * 1e6, 1e-2), color=color, lw=0.8,
                           ls=":", label=f"{lab}: multipliers")
    ax[2].set(xlabel="step", ylabel="contact CPU time per step (µs)",
              title="(c) contact CPU per step (min of repeats; noisy)")
    ax[2].legend(fontsize=7)
    fig.tight_layout()
    return fig


# ----------------------------------------------------------------------------- part 2

def penalty_sweep(cfg: dict, writer, references: dict | None = None) -> dict:
    """Uniform and mass-scaled penalties against the coupled bound, for each radius."""
    p, sw = cfg["punch"], cfg["penalty_sweep"]
    out = {"radii": {}}
    for radius in sw["radii"]:
        ref = (references or {}).get(radius) or run_punch(cfg, FILM("fast"), radius)
        d, kappa = ref["d"], ref["kappa"]
        from ..contact.penalty import lambda_max_diag_plus_rank_one

        lam = lambda_max_diag_plus_rank_one(d, kappa, np.ones(d.size))
        rows = []
        cases = [("uniform", float(v), Penalty(float(v))) for v in sorted(sw["p_values"])]
        # uniform p placed exactly at beta_max = 0.9, 0.99, 1 (p = beta / lambda_max(S))
        cases += [("uniform", float(b) / lam, Penalty(float(b) / lam)) for b in (0.9, 0.99, 1.0)]
        cases += [("mass_scaled", float(b), Penalty("scaled", beta_target=float(b)))
                  for b in sw["beta_targets"]]
        for family, value, method in cases:
            rec = run_punch(cfg, method, radius)
            m = metrics(rec, ref, p["pulse"])
            info = rec["info"]
            # uniform: p_i = p; mass-scaled: p_i = c / d_i with c = p_min * max(d)
            pi = np.full(d.size, info["p_min"]) if family == "uniform" else info["p_min"] * d.max() / d
            m.update({"family": family, "value": value, "beta_max": info["beta_max"],
                      "p_min": info["p_min"], "p_max": info["p_max"],
                      # the paper's view: the per-pair ratio p_i S_ii, near the axis and at the rim
                      "beta_ii_axis": float(pi[0] * d[0]), "beta_ii_rim": float(pi[-1] * d[-1]),
                      "state": classify(m)})
            rows.append(m)
        stable_uniform = [r for r in rows if r["family"] == "uniform" and r["state"] == "stable"]
        best = min(stable_uniform, key=lambda r: r["err_u"]) if stable_uniform else None
        first_bad = min((r["beta_max"] for r in rows if r["state"] != "stable"), default=math.inf)
        last_good = max((r["beta_max"] for r in rows if r["state"] == "stable"), default=0.0)
        force_peak = p["pulse"]["peak"] * math.pi * radius ** 2
        u_rms = float(np.sqrt(np.mean(ref["history"]["punch_u"][ref["history"]["time"] <= p["pulse"]["t_end"]] ** 2)))
        for r in rows:  # the rigid-mode estimate: penetration (1 - beta) / beta * F dt^2 / m_p
            b_ = r["beta_max"]
            r["predicted_err_u"] = abs(1.0 - b_) / b_ * force_peak * kappa / u_rms if b_ > 0 else math.inf
        out["radii"][f"{radius:g}"] = {
            "force_peak": force_peak, "u_rms_film": u_rms, "overshoot_scale": force_peak * kappa,
            "n_constraints": int(d.size), "lambda_max_S": lam, "p_critical_uniform": BETA_BOUND / lam,
            "kappa": kappa, "d_axis": float(d[0]), "d_rim": float(d[-1]), "rows": rows,
            "best_uniform": None if best is None else {"p": best["value"], "err_u": best["err_u"],
                                                        "beta_max": best["beta_max"]},
            "largest_stable_beta": last_good, "smallest_unstable_beta": first_bad,
        }
        log(f"  R_z = {radius:g} m: uniform p critical {BETA_BOUND / lam:.3g} N/m; stable up to "
            f"beta_max {last_good:.3g}, unstable from {first_bad:.3g}; best uniform "
            + ("none" if best is None else f"p = {best['value']:.3g} (error {best['err_u']:.3g})"))
    _sweep_figure(out, writer)
    writer.json("punch_penalty_sweep", out)
    return out


def _sweep_figure(out, writer):
    plt = pyplot()
    fig, ax = plt.subplots(1, 3, figsize=(16, 4.4))
    colors = {}
    for k, (radius, res) in enumerate(out["radii"].items()):
        colors[radius] = f"C{k}"
        for family, marker in (("uniform", "o"), ("mass_scaled", "^")):
            rows = [r for r in res["rows"] if r["family"] == family]
            x = [r["beta_max"] for r in rows]
            y = [min(r["err_u"], 1e3) for r in rows]
            face = [colors[radius] if r["state"] == "stable" else "none" for r in rows]
            ax[0].scatter(x, y, marker=marker, facecolors=face, edgecolors=colors[radius], s=36,
                          label=f"R_z={radius} m, {'uniform p' if family == 'uniform' else 'p ∝ ring mass'}")
            ax[2].scatter([r["beta_ii_rim"] for r in rows], y, marker=marker, facecolors=face,
                          edgecolors=colors[radius], s=36)
        rows = sorted((r for r in res["rows"] if r["family"] == "uniform"), key=lambda r: r["value"])
        ax[1].loglog([r["value"] for r in rows], [min(r["err_u"], 1e3) for r in rows], "-o",
                     color=colors[radius], ms=4, label=f"R_z={radius} m ({res['n_constraints']} constraints)")
        ax[1].axvline(res["p_critical_uniform"], color=colors[radius], ls=":", lw=1)
    ax[0].axvline(BETA_BOUND, color="k", ls="--", lw=1)
    for res in out["radii"].values():
        xs = np.logspace(-3, np.log10(0.999), 200)
        ax[0].plot(xs, (1 - xs) / xs * res["overshoot_scale"] / res["u_rms_film"], color="0.6", lw=0.8)
    ax[0].axvline(1.0, color="0.5", ls=":", lw=1)
    ax[0].set(xscale="log", yscale="log", xlabel="β_max = p λ_max(S)  (coupled, with the punch)",
              ylabel="rel. L2 error of u_p vs FILM (loaded window)",
              title="(a) filled: stable, open: energy gain/chatter/diverged; dashed 4/3\n"
                    "grey: (1-β)/β F dt²/m_p over rms u_p (rigid-mode estimate)")
    ax[0].legend(fontsize=6)
    ax[1].set(xlabel="uniform p (N/m)", ylabel="rel. L2 error of u_p vs FILM",
              title="(b) uniform p; dotted: p at the coupled bound")
    ax[1].legend(fontsize=7)
    ax[2].set(xscale="log", yscale="log", xlabel="per-pair p_i S_ii at the rim (the paper's view)",
              ylabel="rel. L2 error of u_p vs FILM", title="(c) the per-pair ratio does not separate\nstable from unstable")
    fig.tight_layout()
    writer.figure("punch_penalty_sweep", fig)
