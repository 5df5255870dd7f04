"""Study part 4: speed against accuracy on the bar impact.

Every method and setting on at least three meshes (h halved, dt with it). Error:
the relative L2 distance of the sigma_zz history at the observation point from
the mesh-converged reference over c1 t / a <= window, and the largest
penetration. Cost: the contact CPU time (the sum over steps of detection +
solve + update) and the whole run (wall time of the loop). A point is on the
Pareto front if no other point is both cheaper and more accurate.
"""
from __future__ import annotations

import numpy as np

from ..contact import DME, FILM, Penalty
from .bars import P_HIGH, P_PAPER, run_bar
from .common import contact_cpu, dominated, log, pareto_front, pyplot, rel_l2


def methods():
    return [
        ("film", "FILM", lambda: FILM()),
        ("dme_e0", "DME e=0", lambda: DME(0.0)),
        ("dme_e1", "DME e=1", lambda: DME(1.0)),
        ("dme_e0_paper", "DME e=0 equal weights", lambda: DME(0.0, "paper")),
        ("p_paper", "penalty 1.19e10", lambda: Penalty(P_PAPER)),
        ("p_high", "penalty 5e10", lambda: Penalty(P_HIGH)),
        ("p_auto_iom", "penalty auto 1/mean(S_ii)", lambda: Penalty("auto", auto_reading="inverse_of_mean")),
        ("p_scaled", "penalty scaled β=1", lambda: Penalty("scaled")),
    ]


def study(cfg: dict, writer, ref: dict) -> dict:
    t_win = ref["window"]
    finest = ref["levels"][-1]
    points = []
    for h in cfg["accuracy"]["h"]:
        for key, label, make in methods():
            rec = run_bar(cfg, make(), h, t_win + 2 * cfg["bars"]["dt"] * h / cfg["bars"]["h"],
                          output_every=200)
            hist = rec["history"]
            inside = hist["time"] <= t_win
            pen = -np.minimum(hist["min_gap"][inside], 0.0)
            points.append({
                "method": key, "label": label, "h": h, "status": rec["status"],
                "beta_max": rec["info"].get("beta_max"),
                "err_sigma": rel_l2(hist["time"], hist["sigma_zz_obs"], finest["time"], finest["sigma"],
                                    (0.0, t_win)),
                "max_penetration": float(np.nanmax(pen)) if np.all(np.isfinite(pen)) else float("inf"),
                "cpu_contact": float(np.nansum(contact_cpu(hist))),
                "cpu_run": float(rec["summary"]["wall_time"]),
                "n_dofs": rec["n_dofs"], "steps": int(rec["summary"]["n_steps"]),
            })
        log(f"  h = {h:g} m: " + ", ".join(f"{p['method']} {p['err_sigma']:.3g}"
                                           for p in points if p["h"] == h))
    finite = [i for i, p in enumerate(points) if np.isfinite(p["err_sigma"])]
    fronts = {}
    for cost in ("cpu_run", "cpu_contact"):
        pts = [(points[i][cost], points[i]["err_sigma"]) for i in finite]
        fronts[cost] = [finite[j] for j in pareto_front(pts)]
    # the exact property the front must have (checked here and in the tests)
    for cost, front in fronts.items():
        pts = [(points[i][cost], points[i]["err_sigma"]) for i in finite]
        for j, i in enumerate(finite):
            assert (i in front) == (not dominated(pts, j))
    res = {"points": points, "front_cpu_run": fronts["cpu_run"], "front_cpu_contact": fronts["cpu_contact"],
           "window": t_win, "reference_h": finest["h"]}
    _figure(res, writer)
    writer.json("accuracy_pareto", res)
    return res


MARKERS = {"film": "o", "dme_e0": "s", "dme_e1": "D", "dme_e0_paper": "P", "p_paper": "v",
           "p_high": "^", "p_auto_iom": "<", "p_scaled": ">"}


def _figure(res, writer):
    plt = pyplot()
    points = res["points"]
    hs = sorted({p["h"] for p in points}, reverse=True)
    colors = {h: f"C{k}" for k, h in enumerate(hs)}
    fig, ax = plt.subplots(1, 3, figsize=(17, 4.8))
    for i, (cost, front, title) in enumerate((("cpu_run", res["front_cpu_run"], "whole run (loop wall time)"),
                                              ("cpu_contact", res["front_cpu_contact"], "contact only"))):
        for p in points:
            if not np.isfinite(p["err_sigma"]):
                continue
            ax[i].scatter(p[cost], min(p["err_sigma"], 10), marker=MARKERS[p["method"]],
                          color=colors[p["h"]], s=40, edgecolors="k" if p["status"] == "completed" else "r")
        fx = [points[k][cost] for k in front]
        fy = [points[k]["err_sigma"] for k in front]
        ax[i].step(fx, fy, where="post", color="k", lw=1.2, label="Pareto front")
        ax[i].scatter(fx, fy, s=160, facecolors="none", edgecolors="k", lw=1.5)
        ax[i].set(xscale="log", yscale="log", xlabel=f"CPU time, {title} (s; noisy)",
                  ylabel="rel. L2 error of σ_zz history vs reference",
                  title=f"({'ab'[i]}) error vs {title}")
    for p in points:
        ax[2].scatter(max(p["cpu_contact"], 1e-6), max(p["max_penetration"], 1e-16), marker=MARKERS[p["method"]],
                      color=colors[p["h"]], s=40, edgecolors="k")
    ax[2].set(xscale="log", yscale="log", xlabel="contact CPU time (s)",
              ylabel="max penetration (m; 1e-16 = none)", title="(c) penetration vs contact cost")
    handles = [plt.Line2D([], [], marker=MARKERS[k], ls="", color="0.5", label=lab) for k, lab, _ in methods()]
    handles += [plt.Line2D([], [], marker="o", ls="", color=colors[h], label=f"h = {h * 1e3:g} mm") for h in hs]
    ax[2].legend(handles=handles, fontsize=7, loc="center right")
    ax[0].legend(fontsize=8)
    fig.tight_layout()
    writer.figure("accuracy_pareto", fig)
