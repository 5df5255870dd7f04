"""Study part 5: where each method goes unstable.

(a) dt / dt_crit sweeps (dt_crit = 2 / omega_max converged by SLEPc, runs above
    the element bound forced) on the bars and on the punch: FILM and DME are
    stable up to dt_crit; a fixed penalty's beta grows as dt^2 and crosses the
    bound 4/3 earlier, at dt / dt_crit = sqrt(4/3 / beta(dt_crit)).
(b) the stability-scaled penalty at beta_max on both sides of 4/3: the punch
    under a held force (does the contact settle, chatter, gain energy?) and the
    bars (no coupling: every pair at beta).
(c) long runs (1e5 steps) of the bars: the energy balance error of each method,
    beside two controls without contact: a clamped bar (no drift) and a free
    bar that drifts (K u is then a round-off of |K| |u|).
"""
from __future__ import annotations

import math

import numpy as np

from .. import scenes
from ..contact import DME, FILM, Penalty
from .bars import P_PAPER, run_bar
from .common import BETA_BOUND, flips, log, pyplot, run_recorded, settings
from .punch import run_punch


def _unstable_bar(rec, e0: float, n_pairs: int) -> tuple[str, dict]:
    e = rec["energy"]
    gain = float(np.nanmax(e["contact_work"])) / e0 if e["contact_work"].size else 0.0
    grow = float(np.nanmax(e["total"])) / e0 if e["total"].size else math.inf
    nflips = flips(rec["history"]["n_active"])
    m = {"contact_energy_gain_rel": gain, "energy_max_rel": grow, "flips": nflips,
         "status": rec["status"], "stopped_at": rec["stopped_at"]}
    if rec["status"] != "completed" or not math.isfinite(grow) or grow > 2.0:
        return "diverged", m
    if gain > 0.01 or grow > 1.01:
        return "energy gain", m
    if nflips > 3 * n_pairs + 4:  # each pair closes and opens about once in this scene
        return "chatter", m
    return "stable", m


def _unstable_punch(rec, pulse) -> tuple[str, dict]:
    from .punch import classify, metrics

    m = metrics(rec, rec, pulse)
    state = classify(m)
    return state, m


def dt_sweep(cfg: dict) -> dict:
    st, b, p = cfg["stability"], cfg["bars"], cfg["punch"]
    out = {}
    # --- bars
    probe = scenes.bar_impact(settings(dt=1e-9, n_steps=1, converged_dt=True), FILM(), h=b["h"],
                              radius=b["radius"], striker_length=b["striker_length"],
                              target_length=b["target_length"], observe=None)
    dt_conv, dt_elem = probe.dt_converged, probe.dt_critical
    e0 = 0.5 * probe.body_mass["striker"] * b["v0"] ** 2
    n_pairs = probe.contacts[0].n
    p_bar = st.get("bar_penalty", P_PAPER)
    beta_ref = float((p_bar * probe.contacts[0].s_diagonal()).max()) * (dt_conv / probe.settings.dt) ** 2
    cases = [("film", "FILM", lambda: FILM()), ("dme_e0", "DME e=0", lambda: DME(0.0)),
             ("p_paper", f"penalty {p_bar:.3g}", lambda: Penalty(p_bar)),
             ("p_scaled", "penalty scaled β=1", lambda: Penalty("scaled"))]
    rows = []
    for key, label, make in cases:
        for ratio in st["dt_ratios"]:
            rec = _bar_at(cfg, make(), ratio * dt_conv, st["bar_steps"])
            state, m = _unstable_bar(rec, e0, n_pairs)
            m.update(method=key, label=label, ratio=ratio, state=state, beta_max=rec["info"].get("beta_max"))
            rows.append(m)
    out["bars"] = {"dt_converged": dt_conv, "dt_element_bound": dt_elem, "rows": rows,
                   "penalty_predicted_ratio": math.sqrt(BETA_BOUND / beta_ref)}
    # --- punch
    radius = st["punch_radius"]
    probe = run_punch(cfg, FILM(), radius, n_steps=1, dt=1e-9, converged_dt=True)
    dt_conv_p = probe["dt_converged"]
    beta_ref_p = None
    cases = [("film", "FILM", lambda: FILM()), ("dme", "DME", lambda: DME()),
             ("p_paper", f"penalty {p['p_paper']:.3g}", lambda: Penalty(p["p_paper"])),
             ("p_scaled", "penalty scaled β=1", lambda: Penalty("scaled"))]
    rows = []
    for key, label, make in cases:
        for ratio in st["dt_ratios"]:
            dt = ratio * dt_conv_p
            rec = run_punch(cfg, make(), radius, n_steps=st["punch_steps"], dt=dt, force_dt=True,
                            energy_growth_limit=1e3)
            state, m = _unstable_punch(rec, p["pulse"])
            m.update(method=key, label=label, ratio=ratio, state=state, beta_max=rec["info"].get("beta_max"))
            if key == "p_paper":
                beta_ref_p = rec["info"]["beta_max"] / ratio ** 2
            rows.append(m)
    out["punch"] = {"radius": radius, "dt_converged": dt_conv_p, "dt_element_bound": probe["dt_critical"],
                    "rows": rows, "penalty_predicted_ratio": math.sqrt(BETA_BOUND / beta_ref_p)}
    for scene in ("bars", "punch"):
        res = out[scene]
        res["first_unstable"] = {}
        for key in {r["method"] for r in res["rows"]}:
            bad = [r["ratio"] for r in res["rows"] if r["method"] == key and r["state"] != "stable"]
            good = [r["ratio"] for r in res["rows"] if r["method"] == key and r["state"] == "stable"]
            res["first_unstable"][key] = {"first_unstable": min(bad) if bad else None,
                                          "last_stable": max(good) if good else None}
        log(f"  {scene}: dt_crit converged {res['dt_converged']:.4g} s (element bound "
            f"{res['dt_element_bound']:.4g} s); first unstable dt/dt_crit: "
            + ", ".join(f"{k} {v['first_unstable']}" for k, v in sorted(res["first_unstable"].items()))
            + f"; penalty predicted {res['penalty_predicted_ratio']:.3g}")
    return out


def _bar_at(cfg, method, dt, n_steps):
    b = cfg["bars"]
    s = settings(dt=dt, n_steps=n_steps, output_every=10, force_dt=True, energy_growth_limit=1e3)
    sim = scenes.bar_impact(s, method, h=b["h"], nu=0.3, v0=b["v0"], radius=b["radius"],
                            striker_length=b["striker_length"], target_length=b["target_length"],
                            observe=None)
    c = sim.contacts[0]
    rec = run_recorded(sim)
    rec["info"] = dict(getattr(c.method, "info", {}))
    return rec


def beta_sweep(cfg: dict) -> dict:
    st, p, b = cfg["stability"], cfg["punch"], cfg["bars"]
    radius = st["punch_radius"]
    held = dict(peak=p["pulse"]["peak"], t_rise=1e-5, t_fall=1.0, t_end=2.0)
    rows = []
    for beta in st["beta_targets"]:
        rec = run_punch(cfg, Penalty("scaled", beta_target=beta), radius, n_steps=st["beta_steps"],
                        pulse=held)
        h, e = rec["history"], rec["energy"]
        late = slice(st["beta_steps"] // 2, None)
        energy = float(np.nanmax(np.abs(e["total"]))) if e["total"].size else math.inf
        ke = 0.5 * 0.1 * h["punch_v"][late] ** 2
        ext = float(np.nanmax(np.abs(e["external_work"]))) or 1.0
        cw = e["contact_work"]
        half = e["step"] >= st["beta_steps"] // 2
        late_gain = float(np.nanmax(cw[half]) - cw[half][0]) / ext if half.any() else 0.0
        row = {"beta_target": beta, "beta_max": rec["info"]["beta_max"], "status": rec["status"],
               "flips_late": flips(h["n_active"][late]),
               "punch_ke_late_rel": float(np.nanmax(ke)) / energy if np.all(np.isfinite(ke)) else math.inf,
               "contact_work_max_rel": float(np.nanmax(cw)) / ext,
               "contact_work_late_gain_rel": late_gain,
               "balance_error_rel": rec["summary"].get("energy_balance_error_rel")}
        row["state"] = _state(row["status"], row["flips_late"], row["punch_ke_late_rel"], late_gain)
        row["transient_gain"] = row["contact_work_max_rel"] > 0.01
        rows.append(row)
    bar_rows = []
    probe = None
    for beta in st["beta_targets"]:
        rec = run_bar(cfg, Penalty("scaled", beta_target=beta), b["h"], b["t_end"], output_every=10)
        probe = probe or rec
        e0 = 0.5 * rec["body_mass"]["striker"] * b["v0"] ** 2
        state, m = _unstable_bar(rec, e0, rec["n"])
        h = rec["history"]
        m.update(beta_target=beta, beta_max=rec["info"]["beta_max"], state=state,
                 max_penetration=float(np.nanmax(-np.minimum(h["min_gap"], 0.0))))
        bar_rows.append(m)
    out = {"punch": {"radius": radius, "rows": rows, "steps": st["beta_steps"], "pulse": held},
           "bars": {"rows": bar_rows}}
    log("  punch under a held force: " + ", ".join(f"β {r['beta_max']:.3g}: {r['state']}" for r in rows))
    log("  bars: " + ", ".join(f"β {r['beta_max']:.3g}: {r['state']}" for r in bar_rows))
    return out


def _state(status, nflips, ke_rel, late_gain) -> str:
    """The late half of a held load: 'settles' (the active set holds, the punch rests),
    'chatters' (it flips), 'gains energy' (and the punch keeps kinetic energy, or the
    contact keeps doing positive work)."""
    if status != "completed":
        return "diverged"
    if nflips > 0 and (late_gain > 0.01 or ke_rel > 1e-2):
        return "gains energy"
    if nflips > 0:
        return "chatters"
    return "settles"


def long_runs(cfg: dict) -> dict:
    st, b = cfg["stability"], cfg["bars"]
    n = st["long_steps"]
    every = st["long_output_every"]
    out = {"steps": n, "runs": {}}
    cases = [("film", "FILM", lambda: FILM()), ("dme_e0", "DME e=0", lambda: DME(0.0)),
             ("dme_e1", "DME e=1", lambda: DME(1.0)), ("p_scaled", "penalty scaled β=1", lambda: Penalty("scaled")),
             ("p_paper", "penalty 1.19e10", lambda: Penalty(P_PAPER))]
    for key, label, make in cases:
        s = settings(dt=b["dt"], n_steps=n, output_every=every, history_every=every, energy_growth_limit=1e30)
        sim = scenes.bar_impact(s, make(), h=b["h"], nu=0.3, v0=b["v0"], radius=b["radius"],
                                striker_length=b["striker_length"], target_length=b["target_length"],
                                observe=None)
        rec = run_recorded(sim)
        e = rec["energy"]
        v_target = e["momentum_z_target"] / sim.body_mass["target"]
        v_striker = e["momentum_z_striker"] / sim.body_mass["striker"]
        out["runs"][key] = _long_row(label, rec, e, {"target": v_target, "striker": v_striker})
    for key, label, clamp in (("clamped_bar", "bar, far end clamped (no contact)", True),
                              ("free_bar", "free bar, drifting (no contact)", False)):
        s = settings(cfl=0.9, n_steps=n, output_every=every, history_every=every)
        sim = scenes.elastic_bar(s, h=b["h"], length=0.5, nu=0.3, peak=50e6, structured=False,
                                 clamp_far_end=clamp, t_rise=1e-5, t_fall=3e-5, t_end=4e-5)
        rec = run_recorded(sim)
        e = rec["energy"]
        out["runs"][key] = _long_row(label, rec, e, {"bar": e["momentum_z"] / sim.body_mass["bar"]})
    log("  balance error at the end: " + ", ".join(f"{k} {v['balance_final']:.2g}"
                                                   for k, v in out["runs"].items()))
    return out


def _long_row(label, rec, e, velocities) -> dict:
    t = e["time"]
    drift = {name: np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))])
             for name, v in velocities.items()}
    return {"label": label, "status": rec["status"], "wall": rec["wall"],
            "step": e["step"], "balance_error_rel": e["balance_error_rel"],
            "balance_final": float(e["balance_error_rel"][-1]),
            "balance_max": float(np.nanmax(e["balance_error_rel"])),
            "drift": {k: v for k, v in drift.items()},
            "drift_final": {k: float(v[-1]) for k, v in drift.items()},
            "activation_loss": float(e["activation_loss"][-1]), "total_final": float(e["total"][-1]),
            "total_initial": float(e["total"][0])}


def study(cfg: dict, writer) -> dict:
    res = {"dt": dt_sweep(cfg)}
    res["beta"] = beta_sweep(cfg)
    res["long"] = long_runs(cfg)
    _figures(res, writer)
    for part in ("dt", "beta", "long"):
        writer.json(f"stability_{part}", res[part])
    return res


STATE_COLOR = {"stable": "C2", "settles": "C2", "chatter": "C1", "chatters": "C1", "unstable": "C1",
               "energy gain": "C3", "gains energy": "C3", "diverged": "k"}


def _figures(res, writer):
    plt = pyplot()
    # (a) dt sweeps
    fig, ax = plt.subplots(1, 2, figsize=(13, 3.8))
    for i, scene in enumerate(("bars", "punch")):
        d = res["dt"][scene]
        keys = list(dict.fromkeys(r["method"] for r in d["rows"]))
        for j, key in enumerate(keys):
            rows = [r for r in d["rows"] if r["method"] == key]
            ax[i].scatter([r["ratio"] for r in rows], [j] * len(rows),
                          c=[STATE_COLOR[r["state"]] for r in rows], s=60, edgecolors="k")
        ax[i].set_yticks(range(len(keys)))
        ax[i].set_yticklabels([next(r["label"] for r in d["rows"] if r["method"] == k) for k in keys])
        ax[i].axvline(1.0, color="k", ls="--", lw=1)
        ax[i].axvline(d["penalty_predicted_ratio"], color="C3", ls=":", lw=1.2)
        ax[i].axvline(d["dt_element_bound"] / d["dt_converged"], color="0.5", ls="-.", lw=1)
        ax[i].set(xlabel="dt / dt_crit (converged 2/ω_max)",
                  title=f"({'ab'[i]}) {scene}: green stable, orange chatter, red energy gain, black diverged\n"
                        "dashed: dt_crit; dotted: fixed penalty reaches β=4/3; dash-dot: element bound")
    fig.tight_layout()
    writer.figure("stability_dt", fig)
    # (b) beta sweeps
    fig, ax = plt.subplots(1, 2, figsize=(13, 4))
    rows = res["beta"]["punch"]["rows"]
    x = [r["beta_max"] for r in rows]
    ax[0].semilogy(x, [max(r["punch_ke_late_rel"], 1e-18) for r in rows], "o-", label="punch kinetic energy (late) / energy")
    ax[0].semilogy(x, [max(r["flips_late"], 0.5) for r in rows], "s-", label="flips of the active set (late half)")
    ax[0].semilogy(x, [max(r["contact_work_max_rel"], 1e-18) for r in rows], "^-", label="max contact work / external work")
    for r in rows:
        ax[0].axvspan(r["beta_max"] - 0.005, r["beta_max"] + 0.005, color=STATE_COLOR[r["state"]], alpha=0.4)
    ax[0].axvline(BETA_BOUND, color="k", ls="--")
    ax[0].set(xlabel="β_max (stability-scaled penalty)", title="(a) punch under a held force")
    ax[0].legend(fontsize=7)
    rows = res["beta"]["bars"]["rows"]
    x = [r["beta_max"] for r in rows]
    ax[1].semilogy(x, [max(r["flips"], 0.5) for r in rows], "s-", label="flips of the active set")
    ax[1].semilogy(x, [max(r["contact_energy_gain_rel"], 1e-18) for r in rows], "^-", label="max contact work / E0")
    ax[1].semilogy(x, [max(r["max_penetration"], 1e-18) / 1e-6 for r in rows], "o-", label="max penetration (µm)")
    ax[1].axvline(BETA_BOUND, color="k", ls="--")
    ax[1].set(xlabel="β (every pair)", title="(b) bars")
    ax[1].legend(fontsize=7)
    fig.tight_layout()
    writer.figure("stability_beta", fig)
    # (c) long runs
    fig, ax = plt.subplots(1, 2, figsize=(13, 4))
    for key, run in res["long"]["runs"].items():
        ls = "--" if key.endswith("bar") else "-"
        ax[0].loglog(np.maximum(run["step"], 1), np.maximum(run["balance_error_rel"], 1e-17), ls, label=run["label"])
        name = next(iter(run["drift"]))
        drift = run["drift"]["target"] if "target" in run["drift"] else run["drift"][name]
        ax[1].loglog(np.maximum(np.abs(drift), 1e-9), np.maximum(run["balance_error_rel"], 1e-17), ls,
                     label=run["label"])
    ax[0].set(xlabel="step", ylabel="|energy balance error| / energy scale", title="(a) balance error over 1e5 steps")
    ax[1].set(xlabel="drift of the moving body (m)", ylabel="|energy balance error| / energy scale",
              title="(b) the error follows the drift (K u of a rigid shift is round-off)")
    ax[0].legend(fontsize=7)
    fig.tight_layout()
    writer.figure("stability_long", fig)
