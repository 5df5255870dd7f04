"""Study part 6: model no more than a scene needs.

For the punch scene, what each modelling choice buys, measured against a
richer model:

(a) the domain: block width and depth against the distance the P wave runs in
    the 400 steps (c1 t = 0.86 m); the chosen 6.9 m x 0.45 m block against
    smaller ones and a larger reference (8 m x 0.9 m);
(b) the mesh: surface spacing and grading with depth against the shortest
    pulse feature (the 10 us rise, c1 x 10 us = 5.9 cm), against a mesh refined
    twice at the surface and graded half as fast;
(c) the punch: the rigid single node against a deformable punch cylinder
    (meshing.punch_on_block, faces paired node to node, FILM) whose stiffness
    and lightness approach the rigid, massless idealisation, and what each
    costs in time step and steps.

Errors are relative L2 distances over the loaded window [0, 100 us] of the
punch displacement (or the block surface displacement under the punch), the
contact force and, for the mesh, sigma_zz at depth on the axis.
"""
from __future__ import annotations

import math

import numpy as np

from .. import loads, meshing
from ..bodies import Body, DeformableModel
from ..contact import FILM, pair_surfaces
from ..materials import LinearElastic
from ..simulation import Simulation
from .common import C1, E, RHO, log, pyplot, rel_l2, run_recorded, settings
from .config import PUNCH_BLOCK
from .punch import run_punch


def deformable_punch(s, method, radius: float = 1.0, height: float = 0.05, e_ratio: float = 1.0,
                     rho_ratio: float = 1.0, pulse: dict | None = None, block: dict | None = None,
                     probes=()) -> Simulation:
    """The punch scene with a deformable punch cylinder (radius, height in m; Young's
    modulus and density as multiples of the block's steel) resting on the block, its
    bottom face paired node to node with the block surface under it. The pulse is a
    pressure (Pa) on the punch top: the same total force sigma(t) pi R_z^2."""
    block = dict(PUNCH_BLOCK if block is None else block)
    tmesh = meshing.punch_on_block(punch_radius=radius, punch_height=height, **block)
    steel = LinearElastic(E=E, nu=0.3, density=RHO)
    punch = LinearElastic(E=E * e_ratio, nu=0.3, density=RHO * rho_ratio)
    model = DeformableModel(tmesh, [Body("block", steel), Body("punch", punch)])
    pulse = loads.Trapezoid(**(pulse or dict(peak=200e6, t_rise=1e-5, t_fall=9e-5, t_end=1e-4)))
    sim = Simulation(model, s, fixed=[model.facet_dofs("bottom", 1)],
                     loads=[loads.SurfaceLoad(model, "punch_top", pulse)])
    sim.add_contact(pair_surfaces(model, "contact", "punch_contact"), method)
    for name, point, quantity in probes:
        sim.add_probe(name, point, quantity)
    return sim


def _errors(rec, ref, keys, window) -> dict:
    h, hr = rec["history"], ref["history"]
    return {f"err_{name}": rel_l2(h["time"], h[a], hr["time"], hr[b], window) for name, a, b in keys}


def domain(cfg: dict) -> dict:
    p, m = cfg["punch"], cfg["modelling"]
    # the loaded window: after it the block's rebound launches the light punch into a free
    # flight whose speed amplifies any difference (mesh noise included) linearly in time
    window = (0.0, p["pulse"]["t_end"])
    chosen = dict(p["block"])
    keys = [("u", "punch_u", "punch_u"), ("force", "punch_force", "punch_force")]
    out = {"wave_distance": C1 * p["dt"] * p["n_steps"], "chosen": {"width": chosen["width"],
                                                                    "depth": chosen["depth"]}}
    for what, values, radius in (("width", m["widths"], max(p["radii"])), ("depth", m["depths"], min(p["radii"]))):
        ref_block = dict(chosen, **m["reference_block"])
        ref = run_punch(cfg, FILM(), radius, block=ref_block)
        rows = []
        for v in values:
            block = dict(chosen, **{what: v})
            rec = ref if block == ref_block else run_punch(cfg, FILM(), radius, block=block)
            row = {what: v, "n_cells": rec["n_cells"], "wall": rec["wall"], **_errors(rec, ref, keys, window)}
            # when the echo of that boundary reaches the punch edge / the surface (s)
            if what == "width":
                row["echo_time"] = 2 * (v - radius) / C1
            else:
                row["echo_time"] = 2 * v / C1
            rows.append(row)
        out[what] = {"radius": radius, "reference": ref_block, "reference_cells": ref["n_cells"], "rows": rows}
        log(f"  {what} (R_z = {radius:g} m): " + ", ".join(
            f"{r[what]:g} m: u error {r['err_u']:.2g}, {r['n_cells']} cells" for r in rows))
    return out


def mesh(cfg: dict) -> dict:
    p, m = cfg["punch"], cfg["modelling"]
    radius = min(p["radii"])
    window = (0.0, p["pulse"]["t_end"])
    base = dict(p["block"])
    probes = [("sigma_zz_axis", (0.0, -0.1), "sigma_zz")]
    keys = [("u", "punch_u", "punch_u"), ("force", "punch_force", "punch_force"),
            ("sigma", "sigma_zz_axis", "sigma_zz_axis")]
    t_end = p["dt"] * p["n_steps"]

    def block_for(k, grading):
        return dict(base, h_surface=base["h_surface"] / k, grading=grading,
                    breaks=tuple((r, int(round(n * k))) for r, n in base["breaks"]))

    def run(k, grading):
        dt = p["dt"] / max(1.0, k)
        return run_punch(cfg, FILM(), radius, block=block_for(k, grading), dt=dt,
                         n_steps=int(round(t_end / dt)), probes=probes)

    ref = run(*m["mesh_reference"])
    rows = []
    for k, grading in m["mesh"]:
        rec = ref if (k, grading) == tuple(m["mesh_reference"]) else run(k, grading)
        h_s = base["h_surface"] / k
        rows.append({"k": k, "h_surface": h_s, "grading": grading, "n_cells": rec["n_cells"],
                     "steps": int(rec["summary"]["n_steps"]), "wall": rec["wall"],
                     "elements_per_rise": C1 * p["pulse"]["t_rise"] / h_s,
                     "h_at_probe": h_s + grading * 0.1,
                     "chosen": h_s == base["h_surface"] and grading == base["grading"],
                     "series": {"time": rec["history"]["time"], "sigma": rec["history"]["sigma_zz_axis"]},
                     **_errors(rec, ref, keys, window)})
    log("  mesh (R_z = {:g} m): ".format(radius) + ", ".join(
        f"h {r['h_surface'] * 1e3:g} mm/g {r['grading']:g}: u {r['err_u']:.2g}, sigma {r['err_sigma']:.2g}"
        for r in rows))
    return {"radius": radius, "reference": {"k": m["mesh_reference"][0], "grading": m["mesh_reference"][1],
                                            "n_cells": ref["n_cells"]}, "rows": rows}


def punch_model(cfg: dict) -> dict:
    p, m = cfg["punch"], cfg["modelling"]
    radius = min(p["radii"])
    window = (0.0, p["pulse"]["t_end"])
    t_end = p["dt"] * p["n_steps"]
    points = [("uz_centre", (0.0, -1e-4), "u_z"), ("uz_half", (0.5 * radius, -1e-4), "u_z")]
    rigid = run_punch(cfg, FILM(), radius, probes=points)
    rigid["history"]["contact_force"] = rigid["history"]["punch_force"]
    keys = [("uz_centre", "uz_centre", "uz_centre"), ("uz_half", "uz_half", "uz_half"),
            ("force", "contact_force", "contact_force")]
    rows = [{"model": "rigid node (0.1 kg)", "e_ratio": math.inf, "rho_ratio": 0.0, "n_dofs": rigid["n_dofs"],
             "dt": rigid["dt"], "steps": int(rigid["summary"]["n_steps"]), "wall": rigid["wall"],
             "err_uz_centre": 0.0, "err_uz_half": 0.0, "err_force": 0.0, "mass": 0.1,
             "series": _series(rigid)}]
    for e_ratio, rho_ratio in m["punch_materials"]:
        s = settings(cfl=0.9, t_end=t_end, output_every=50)
        sim = deformable_punch(s, FILM(), radius=radius, height=m["punch_height"], e_ratio=e_ratio,
                               rho_ratio=rho_ratio, pulse=p["pulse"], block=p["block"], probes=points)
        mass = sim.body_mass["punch"]  # kg
        rec = run_recorded(sim)
        rows.append({"model": f"deformable, E×{e_ratio:g}, ρ×{rho_ratio:g}", "e_ratio": e_ratio,
                     "rho_ratio": rho_ratio, "n_dofs": rec["summary"]["n_dofs"], "dt": s.dt,
                     "steps": int(rec["summary"]["n_steps"]), "wall": rec["wall"], "mass": mass,
                     "wave_speed_ratio": math.sqrt(e_ratio / rho_ratio),
                     "series": _series(rec), **_errors(rec, rigid, keys, window)})
    log("  punch model (R_z = {:g} m): ".format(radius) + ", ".join(
        f"{r['model']}: centre u error {r['err_uz_centre']:.2g}, {r['steps']} steps" for r in rows))
    return {"radius": radius, "height": m["punch_height"], "rows": rows}


def _series(rec):
    h = rec["history"]
    return {"time": h["time"], "uz_centre": h["uz_centre"], "uz_half": h["uz_half"],
            "force": h["contact_force"]}


def study(cfg: dict, writer) -> dict:
    res = {"domain": domain(cfg), "mesh": mesh(cfg), "punch": punch_model(cfg),
           "tolerance": cfg["modelling"]["tolerance"]}
    _figure(res, writer)
    writer.json("modelling", res)
    return res


def _figure(res, writer):
    plt = pyplot()
    fig, ax = plt.subplots(1, 4, figsize=(20, 4.3))
    tol = res["tolerance"]
    for what, marker in (("width", "o"), ("depth", "s")):
        d = res["domain"][what]
        ax[0].semilogy([r[what] for r in d["rows"]], [max(r["err_u"], 1e-8) for r in d["rows"]], marker + "-",
                       label=f"block {what} (R_z = {d['radius']:g} m): u_p")
        ax[0].semilogy([r[what] for r in d["rows"]], [max(r["err_force"], 1e-8) for r in d["rows"]],
                       marker + ":", label=f"block {what}: F_punch")
    ax[0].axhline(tol, color="k", ls="--", lw=1)
    ax[0].set(xlabel="block width or depth (m)", ylabel="rel. L2 error vs 8 m x 0.9 m block",
              title="(a) domain size (dashed: study tolerance)")
    ax[0].legend(fontsize=7)
    rows = res["mesh"]["rows"]
    for key, marker, lab in (("err_u", "o", "u_p"), ("err_sigma", "s", "σ_zz at (0, -0.1 m)")):
        ax[1].loglog([r["n_cells"] for r in rows], [max(r[key], 1e-8) for r in rows], marker, label=lab)
    for r in rows:
        ax[1].annotate(f"{r['h_surface'] * 1e3:g} mm/{r['grading']:g}" + (" (chosen)" if r["chosen"] else ""),
                       (r["n_cells"], max(r["err_sigma"], 1e-8)), fontsize=6)
    ax[1].axhline(tol, color="k", ls="--", lw=1)
    ax[1].set(xlabel="cells", ylabel="rel. L2 error vs the finest mesh",
              title="(b) surface spacing / grading with depth")
    ax[1].legend(fontsize=7)
    for r in rows:
        s = r["series"]
        ax[2].plot(np.asarray(s["time"]) * 1e6, np.asarray(s["sigma"]) / 1e6, lw=0.9,
                   label=f"h {r['h_surface'] * 1e3:g} mm, g {r['grading']:g}")
    ax[2].set(xlabel="t (µs)", ylabel="σ_zz at (0, -0.1 m) (MPa)", title="(c) the 10 µs rise at depth")
    ax[2].legend(fontsize=6)
    for r in res["punch"]["rows"]:
        s = r["series"]
        ax[3].plot(np.asarray(s["time"]) * 1e6, np.asarray(s["uz_centre"]) * 1e3, lw=1.0,
                   label=f"{r['model']}: {r['steps']} steps")
    ax[3].set(xlabel="t (µs)", ylabel="block surface u_z at the axis (mm)",
              title=f"(d) rigid node vs deformable punch (H = {res['punch']['height']:g} m)")
    ax[3].legend(fontsize=6)
    fig.tight_layout()
    writer.figure("modelling", fig)
