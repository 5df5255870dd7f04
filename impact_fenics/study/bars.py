"""Study part 3: the longitudinal impact of thick bars (paper Section 3.2).

Per-pair gap and contact force of every method (the paper's Figs 8-10, from
the runs' contact_pairs.h5), and sigma_zz at r = 0.1 m, z = 0.2 m (DG0 value of
the cell holding the point) as sigma_zz / (rho c1 v0 / 2) against c1 t / a,
against a mesh-converged reference: the same scene with FILM on meshes
refined by halving h (and dt with it) until the history stops changing.
"""
from __future__ import annotations

import numpy as np

from .. import scenes
from ..contact import DME, FILM, Penalty
from .common import (C1, RHO, TWO_PI, Scratch, flips, log, pyplot, read_pairs, rel_l2,
                     run_recorded, settings)

P_PAPER = 1.19e10  # N/m, the paper's "average of the diagonal" (Section 3.2)
P_HIGH = 5e10  # N/m, the paper's higher value


def methods():
    """(key, label, factory) of the bar methods."""
    return [
        ("film", "FILM", lambda: FILM()),
        ("dme_e0", "DME e=0", lambda: DME(0.0)),
        ("dme_e1", "DME e=1", lambda: DME(1.0)),
        ("dme_e0_paper", "DME e=0, equal-weight positions", lambda: DME(0.0, "paper")),
        ("dme_e1_paper", "DME e=1, equal-weight positions", lambda: DME(1.0, "paper")),
        ("p_paper", "penalty 1.19e10", lambda: Penalty(P_PAPER)),
        ("p_high", "penalty 5e10", lambda: Penalty(P_HIGH)),
        ("p_paper_2pi", "penalty 1.19e10·2π", lambda: Penalty(P_PAPER * TWO_PI)),
        ("p_auto_iom", "penalty auto, 1/mean(S_ii)", lambda: Penalty("auto", auto_reading="inverse_of_mean")),
        ("p_auto_moi", "penalty auto, mean(1/S_ii)", lambda: Penalty("auto", auto_reading="mean_of_inverse")),
        ("p_scaled", "penalty scaled (β=1)", lambda: Penalty("scaled")),
    ]


def sigma_scale(v0: float) -> float:
    """rho c1 v0 / 2 (Pa)."""
    return RHO * C1 * v0 / 2.0


def window_time(cfg: dict) -> float:
    """End (s) of the compared window c1 t / a <= window_c1t_a."""
    b = cfg["bars"]
    return b["window_c1t_a"] * b["radius"] / C1


def run_bar(cfg: dict, method, h: float, t_end: float, out: str | None = None,
            **kw) -> dict:
    """One bar impact (dt scaled with h from the paper's 1 us at h = 0.02 m), recorded."""
    b = cfg["bars"]
    dt = b["dt"] * h / b["h"]
    s = settings(dt=dt, t_end=t_end, out=out, output_every=kw.pop("output_every", 50),
                 energy_growth_limit=1e30, **kw)
    sim = scenes.bar_impact(s, method, h=h, nu=0.3, v0=b["v0"], radius=b["radius"],
                            striker_length=b["striker_length"], target_length=b["target_length"],
                            observe=tuple(b["observe"]))
    c = sim.contacts[0]
    rec = run_recorded(sim)
    rec.update(n=c.n, h=h, dt=dt, info=dict(getattr(c.method, "info", {})),
               n_cells=rec["summary"]["n_cells"], n_dofs=rec["summary"]["n_dofs"],
               d=c.s_diagonal().copy(), body_mass=dict(sim.body_mass))
    return rec


def reference(cfg: dict, writer) -> dict:
    """FILM on the refinement levels; the change of the sigma_zz history between levels."""
    b = cfg["bars"]
    t_win = window_time(cfg)
    scale = sigma_scale(b["v0"])
    levels = []
    for h in b["reference_h"]:
        rec = run_bar(cfg, FILM(), h, t_win + 2 * b["dt"] * h / b["h"], output_every=500)
        hist = rec["history"]
        levels.append({"h": h, "dt": rec["dt"], "n_cells": rec["n_cells"], "n_dofs": rec["n_dofs"],
                       "wall": rec["wall"], "time": hist["time"], "sigma": hist["sigma_zz_obs"],
                       "steps": int(rec["summary"]["n_steps"])})
        log(f"  reference h = {h:g} m: {rec['n_cells']} cells, {rec['summary']['n_steps']} steps, "
            f"{rec['wall']:.1f} s")
    finest = levels[-1]
    changes = []
    for a, c in zip(levels[:-1], levels[1:]):
        changes.append(rel_l2(a["time"], a["sigma"], c["time"], c["sigma"], (0.0, t_win)))
    for lev in levels[:-1]:
        lev["error_vs_finest"] = rel_l2(lev["time"], lev["sigma"], finest["time"], finest["sigma"],
                                        (0.0, t_win))
    # observed order of the changes, and a Richardson-type bound on the finest level's error
    ratios = [changes[k + 1] / changes[k] for k in range(len(changes) - 1)]
    q = ratios[-1] if ratios else 0.5
    tail = changes[-1] * q / (1 - q) if 0 < q < 1 else float("inf")
    res = {"levels": levels, "changes": changes, "change_ratios": ratios, "window": t_win,
           "finest_error_estimate": tail, "sigma_scale": scale, "c1": C1}
    log("  reference changes between levels: " + ", ".join(f"{c:.3g}" for c in changes))
    return res


def paper_runs(cfg: dict, writer, ref: dict) -> dict:
    """Every method on the paper's mesh; figures bars_contact.png and bars_stress.png."""
    b = cfg["bars"]
    scratch = Scratch()
    t_win = ref["window"]
    finest = ref["levels"][-1]
    runs = {}
    try:
        for key, label, make in methods():
            rec = run_bar(cfg, make(), b["h"], b["t_end"], out=scratch.sub(key), output_every=25)
            rec["pairs"] = read_pairs(scratch.sub(key) + "/contact_pairs.h5")
            rec["label"] = label
            runs[key] = rec
    finally:
        scratch.close()
    res = {"h": b["h"], "dt": b["dt"], "t_end": b["t_end"], "methods": {}}
    first = next(iter(runs.values()))
    res["n_cells"], res["n_dofs"], res["n_pairs"] = first["n_cells"], first["n_dofs"], first["n"]
    res["p_auto_mean_of_inverse"] = runs["p_auto_moi"]["info"]["p_auto_mean_of_inverse"]
    res["p_auto_inverse_of_mean"] = runs["p_auto_moi"]["info"]["p_auto_inverse_of_mean"]
    res["p_paper_2pi"] = P_PAPER * TWO_PI
    res["d"] = first["d"]
    for key, rec in runs.items():
        hist, pairs, e = rec["history"], rec["pairs"], rec["energy"]
        t = hist["time"]
        contact = np.flatnonzero(hist["n_active"] > 0)
        p0 = first["body_mass"]["striker"] * b["v0"]
        e0 = 0.5 * first["body_mass"]["striker"] * b["v0"] ** 2
        res["methods"][key] = {
            "label": rec["label"], "status": rec["status"], "stopped_at": rec["stopped_at"],
            "beta_max": rec["info"].get("beta_max"),
            "err_sigma": rel_l2(t, hist["sigma_zz_obs"], finest["time"], finest["sigma"], (0.0, t_win)),
            "max_penetration": float(np.nanmax(np.maximum(-pairs["gap"], 0.0))),
            "max_penetration_contact": _penetration_while_closed(pairs),
            "contact_start": float(t[contact[0]]) if contact.size else None,
            "contact_end": float(t[contact[-1]]) if contact.size else None,
            "flips": flips(hist["n_active"]),
            "momentum_error_rel": float(np.nanmax(np.abs(e["momentum_z"] - p0)) / p0),
            "energy_final_rel": float(e["total"][-1] / e0),
            "contact_work_max_rel": float(np.nanmax(e["contact_work"]) / e0),
            "balance_error_rel": rec["summary"].get("energy_balance_error_rel"),
            "series": {"time": t, "sigma": hist["sigma_zz_obs"], "pair_time": pairs["time"],
                       "gap": pairs["gap"], "force": pairs["force"], "r": pairs["r"]},
        }
    m = res["methods"]
    res["film_vs_dme_e0_sigma"] = rel_l2(m["film"]["series"]["time"], m["film"]["series"]["sigma"],
                                         m["dme_e0"]["series"]["time"], m["dme_e0"]["series"]["sigma"],
                                         (0.0, t_win))
    res["dme_e1_vs_e0_sigma"] = rel_l2(m["dme_e1"]["series"]["time"], m["dme_e1"]["series"]["sigma"],
                                       m["dme_e0"]["series"]["time"], m["dme_e0"]["series"]["sigma"],
                                       (0.0, t_win))
    res["dme_paper_vs_mass_weighted_sigma"] = rel_l2(
        m["dme_e0_paper"]["series"]["time"], m["dme_e0_paper"]["series"]["sigma"],
        m["dme_e0"]["series"]["time"], m["dme_e0"]["series"]["sigma"], (0.0, t_win))
    res["beta_paper_values"] = {"1.19e10": float((P_PAPER * res["d"]).max()),
                                "5e10": float((P_HIGH * res["d"]).max()),
                                "1.19e10*2pi": float((P_PAPER * TWO_PI * res["d"]).max())}
    for key, v in m.items():
        log(f"  {v['label']:34s} {v['status']:9s} beta {v['beta_max'] if v['beta_max'] is None else round(v['beta_max'], 3)}"
            f"  sigma error {v['err_sigma']:.3g}  max penetration {v['max_penetration']:.3g} m")
    _contact_figure(res, writer)
    _stress_figure(res, ref, cfg, writer)
    writer.json("bars_contact", {k: v for k, v in res.items()})
    writer.json("bars_reference", ref)
    writer.json("bars_stress", {
        "sigma_scale": ref["sigma_scale"], "c1": C1, "radius": b["radius"],
        "reference": [{"h": lev["h"], "time": lev["time"], "sigma": lev["sigma"]} for lev in ref["levels"]],
        "methods": {k: {"label": v["label"], "err_sigma": v["err_sigma"], "time": v["series"]["time"],
                        "sigma": v["series"]["sigma"]} for k, v in res["methods"].items()}})
    return res


def _penetration_while_closed(pairs) -> float:
    gap = pairs["gap"]
    closed = pairs["active"] > 0.5
    return float(np.max(np.maximum(-gap[closed], 0.0))) if closed.any() else 0.0


FIG_ROWS = ("film", "p_paper", "dme_e0", "dme_e1", "p_high", "p_auto_iom", "p_scaled")


def _contact_figure(res, writer):
    plt = pyplot()
    rows = [k for k in FIG_ROWS if k in res["methods"]]
    fig, ax = plt.subplots(len(rows), 2, figsize=(12, 2.3 * len(rows)), sharex=True)
    for i, key in enumerate(rows):
        m = res["methods"][key]
        s = m["series"]
        t = np.asarray(s["pair_time"]) * 1e6
        gap, force = np.asarray(s["gap"]), np.asarray(s["force"])
        for j, r in enumerate(s["r"]):
            ax[i, 0].plot(t, gap[:, j] * 1e6, lw=0.9, label=f"r = {r:.2f} m")
            ax[i, 1].plot(t, force[:, j] / 1e3, lw=0.9)
        beta = "" if m["beta_max"] is None else f", β_max = {m['beta_max']:.2g}"
        ax[i, 0].set_ylabel("gap (µm)")
        ax[i, 1].set_ylabel("force (kN)")
        ax[i, 0].set_title(f"{m['label']}{beta}: gap (< 0 penetration)", fontsize=9)
        ax[i, 1].set_title(f"{m['label']}: contact force per pair", fontsize=9)
        lim = np.nanmax(np.abs(np.asarray(res['methods']['film']['series']['force']))) / 1e3
        ax[i, 1].set_ylim(-0.1 * lim, 2.5 * lim)
        g = gap[np.isfinite(gap)]
        if g.size:
            ax[i, 0].set_ylim(max(g.min() * 1e6, -50) - 1, min(g.max() * 1e6, 200) + 1)
    ax[0, 0].legend(fontsize=6, ncol=2)
    ax[-1, 0].set_xlabel("t (µs)")
    ax[-1, 1].set_xlabel("t (µs)")
    fig.tight_layout()
    writer.figure("bars_contact", fig)


def _stress_figure(res, ref, cfg, writer):
    plt = pyplot()
    scale = ref["sigma_scale"]
    a = cfg["bars"]["radius"]
    fig, ax = plt.subplots(1, 3, figsize=(17, 4.6))
    for k, lev in enumerate(ref["levels"]):
        ax[0].plot(C1 * np.asarray(lev["time"]) / a, np.asarray(lev["sigma"]) / scale, lw=0.9,
                   label=f"h = {lev['h'] * 1e3:g} mm ({lev['n_cells']} cells)")
    ax[0].set(title="(a) FILM under refinement (reference: finest)", xlabel="c1 t / a",
              ylabel="σ_zz / (ρ c1 v0 / 2)  at r = a, z = 0.2 m")
    ax[0].legend(fontsize=7)
    finest = ref["levels"][-1]
    for axis in ax[1:]:
        axis.plot(C1 * np.asarray(finest["time"]) / a, np.asarray(finest["sigma"]) / scale, color="k",
                  lw=2.2, alpha=0.35, label="reference (finest mesh)")
    panels = {1: ("film", "dme_e0", "p_paper", "p_high", "p_auto_iom", "p_scaled"),
              2: ("dme_e0", "dme_e1", "dme_e0_paper", "dme_e1_paper")}
    for i, keys in panels.items():
        for key in keys:
            m = res["methods"][key]
            s = m["series"]
            ax[i].plot(C1 * np.asarray(s["time"]) / a, np.asarray(s["sigma"]) / scale, lw=0.9,
                       label=f"{m['label']} (err {m['err_sigma']:.2f})")
        ax[i].set(xlabel="c1 t / a", ylabel="σ_zz / (ρ c1 v0 / 2)", xlim=(0, cfg["bars"]["window_c1t_a"]))
        lo = np.nanmin(np.asarray(finest["sigma"])) / scale
        ax[i].set_ylim(1.4 * lo, -0.4 * lo)
        ax[i].legend(fontsize=7, loc="lower right")
    ax[1].set_title(f"(b) methods on the paper's mesh (h = {res['h'] * 1e3:g} mm)")
    ax[2].set_title("(c) DME velocity (e) and position schemes")
    fig.tight_layout()
    writer.figure("bars_stress", fig)
