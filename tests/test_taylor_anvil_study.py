"""The Taylor anvil against the rigid wall (long: `make study-taylor-anvil`, deselected
from `make test`; docs/taylor_bar.md, "A deformable anvil").

The rod of docs/taylor_bar.md (copper, finite-strain J2 on Q1, n_r = 4 and 8, 227 m/s, FILM,
the face in unilateral contact) onto a steel anvil (linear elastic, small strain, Q1,
3 R wide and 2 R deep, its bottom held in z: an anvil on a rigid floor) whose E and
density are both scaled by k = 1, 10, ..., 10^4: its wave speed and stable step stay,
its impedance grows k times, so Z_rod / Z_anvil = 0.889 / k (plane-wave impedances
rho c_P). The reference is the unilateral rigid wall (scenes.taylor_bar) on the same rod
mesh, the same fixed step (the segment kind takes a constant step: 2^-28 s at n_r = 4,
2^-29 s at n_r = 8, each below the rod's current limit throughout the run, which the
following step checks) and the same end (21475 and 42950 steps, 80.0 us).

Oracle: the anvil's compliance is O(1 / k), so the rod's figures (axis length, height of
the top axis node above z = 0, impact-face radius, foot radius) converge to the wall's at
first order in Z_rod / Z_anvil. The order is a property of the limit: the softer anvils
are not yet in it (the differences d_k change sign on the way, and k d_k settles only
from k = 100 on; docs/taylor_bar.md gives the table), so the observed order
log10(|d_k| / |d_10k|) between the two stiffest anvils, k = 1000 and 10^4, is asserted in
[0.75, 1.5] (first order told apart from the neighbouring half and second orders: the
band's ends are the midpoints), and each run's ledger within roundoff.ledger. The
one-ulp spread of the wall's run (v0 moved by one ulp: 3e-17 m in the radius at
n_r = 8) is far below the smallest d_k (5e-9 m), so the differences are not round-off. The tables are written to docs/figures/taylor_anvil.json
(one per mesh) and printed.
"""
import json
import math
import os

import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics import scenes
from impact_fenics.contact.plane import foot_radius
from impact_fenics.materials import STEEL, FiniteJ2
from impact_fenics.simulation import Settings
from roundoff import ledger

R, L = 3.2e-3, 32.4e-3  # m
COPPER = FiniteJ2(E=117e9, nu=0.35, density=8930.0, yield_stress=400e6, hardening=100e6)
# n_r, the fixed step (s), the steps to 80.0 us; the smallest limit of the rod's cells
# over the wall's run: 8.8e-9 s at n_r = 4, 3.0e-9 s at n_r = 8
MESHES = {4: (2.0 ** -28, 21475), 8: (2.0 ** -29, 42950)}
SCALES = (1.0, 10.0, 100.0, 1000.0, 10000.0)
FIGURES = ("length", "height", "face_radius", "foot_radius")
OUT = os.path.join(os.path.dirname(__file__), "..", "docs", "figures", "taylor_anvil.json")


def _impedance(m) -> float:
    """rho c_P (kg/m^2/s), the plane-wave impedance."""
    return math.sqrt(m.E * (1 - m.nu) / ((1 + m.nu) * (1 - 2 * m.nu)) * m.density)


def run(scale: float | None, n_r: int, comm=MPI.COMM_WORLD) -> dict:
    """One run on the n_r mesh: the rigid wall (``scale`` None) or the anvil scaled by
    ``scale``."""
    dt, n_steps = MESHES[n_r]
    settings = Settings(quiet=True, plots=False, timers=False, fields=False, energy_every=10)
    if scale is None:
        sim = scenes.taylor_bar(settings, COPPER, n_r=n_r, t_end=n_steps * dt, dt=dt, comm=comm)
        body = "bar"
    else:
        sim = scenes.taylor_anvil(settings, COPPER, anvil_scale=scale, n_r=n_r,
                                  t_end=n_steps * dt, dt=dt, comm=comm)
        body = "rod"
    s = sim.run(extra=sim.scene_figures)
    model = sim.model
    nodes = model.body_dofs(body, 0) // 2
    e = sim.energy.data()
    hist = sim.history.data()
    return {"scale": scale, "status": s["status"], "n_steps": s["n_steps"],
            "length": s["final_length"], "height": L + float(hist["u_z_top"][-1]),
            "face_radius": s["final_face_radius"],
            "foot_radius": foot_radius(nodes, model.node_xy, sim.integrator.u_owned, 0.0,
                                       R / n_r, comm),
            "plastic_work": s["plastic_work"], "eps_p_max": s["eps_p_max"],
            "activation_loss": float(e["activation_loss"][-1]),
            "balance": float(np.abs(e["balance_error"]).max() / sim.ledger.E0),
            "bound": ledger(s["n_steps"], s["n_dofs"])}


def orders(rows: list[dict], wall: dict) -> dict:
    """Per figure, |d_k| = |figure_k - wall| and log10(|d_k| / |d_10k|) between
    successive k."""
    out = {}
    for f in FIGURES:
        d = [abs(r[f] - wall[f]) for r in rows]
        out[f] = {"differences": d,
                  "orders": [math.log10(a / b) if a > 0 and b > 0 else None
                             for a, b in zip(d[:-1], d[1:])]}
    return out


@pytest.mark.study
@pytest.mark.parametrize("n_r", sorted(MESHES))
def test_the_anvil_converges_to_the_wall(comm, n_r):
    wall = run(None, n_r, comm)
    rows = [run(k, n_r, comm) for k in SCALES]
    for r in [wall] + rows:
        assert r["status"] == "completed" and r["n_steps"] == MESHES[n_r][1]
        assert r["balance"] <= r["bound"]
    conv = orders(rows, wall)
    ratio = _impedance(COPPER) / _impedance(STEEL)
    if comm.rank == 0:
        tables = {}
        if os.path.exists(OUT):
            with open(OUT) as f:
                tables = json.load(f)
        tables[str(n_r)] = {"dt": MESHES[n_r][0], "n_steps": MESHES[n_r][1],
                            "z_ratio_steel": ratio, "wall": wall, "anvil": rows,
                            "convergence": conv}
        with open(OUT, "w") as f:
            json.dump(tables, f, indent=1, sort_keys=True)
        print("\nn_r = %d" % n_r)
        print("| anvil | Z_rod/Z_anvil | length (mm) | height (mm) | face radius (mm) | "
              "foot radius (mm) | plastic (J) | max eps_p | activation (J) | balance |")
        print("|---|---|---|---|---|---|---|---|---|---|")
        for r in [wall] + rows:
            name = "rigid wall" if r["scale"] is None else "steel x %g" % r["scale"]
            z = "0" if r["scale"] is None else "%.4g" % (ratio / r["scale"])
            print("| %s | %s | %.5f | %.5f | %.5f | %.5f | %.3f | %.3f | %.3f | %.1e |" % (
                name, z, r["length"] * 1e3, r["height"] * 1e3, r["face_radius"] * 1e3,
                r["foot_radius"] * 1e3, r["plastic_work"], r["eps_p_max"],
                r["activation_loss"], r["balance"]))
        for f in FIGURES:
            print(f, "differences (mm):", " ".join("%.2e" % (d * 1e3)
                                                  for d in conv[f]["differences"]),
                  "orders:", " ".join("-" if o is None else "%.2f" % o
                                      for o in conv[f]["orders"]))
    for f in FIGURES:
        assert 0.75 <= conv[f]["orders"][-1] <= 1.5, (f, conv[f])
