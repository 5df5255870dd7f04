# # Contact of faces whose nodes do not match (node to segment)
#
# Two scenes, each with penalty, FILM or DME enforced node to segment (the
# finer face's nodes as slaves against the two-node segments of the other):
#
# * ``bars``: two nu = 0 steel bars of radius 5 cm and length 0.2 m whose
#   contact faces have 6 and 9 intervals (a non-nested 3:2 ratio); the striker
#   hits at v0 = 5 m/s. The 1D solution: contact stress rho c0 v0 / 2 for
#   2 L / c0 = 79 us, then the velocities are exchanged; the run lasts 120 us.
# * ``nose``: a steel striker with a hemispherical nose (R = 2 cm, 8 intervals on
#   a quarter circle) hits an aluminium block (12 intervals under the nose) at
#   20 m/s; the block face is the slave, so the normals are inclined and both
#   u_r and u_z enter every constraint.
#
#     scripts/mpirun.sh -n 2 .venv/bin/python demos/node_to_segment.py --scene bars --method dme
#     scripts/mpirun.sh -n 2 .venv/bin/python demos/node_to_segment.py --scene nose --method film
#
# The scene files scenes/nts_bars.toml and scenes/nts_nose.toml describe the same runs:
#
#     scripts/mpirun.sh -n 2 .venv/bin/python -m impact_fenics run scenes/nts_nose.toml
#
# Results go to results/nts_<scene>_<method>/ (or --out DIR): fields.xdmf,
# history.csv, contact_pairs.csv (gap, force, active of each slave), energy.csv
# and summary.json.

import argparse
import math

import numpy as np
from mpi4py import MPI

from impact_fenics import scenes
from impact_fenics.errors import user_errors
from impact_fenics.simulation import Settings

RHO, E, V0_BARS, L, A = 7850.0, 200e9, 5.0, 0.2, 0.05
C0 = math.sqrt(E / RHO)


def run(scene: str, method: str, out: str | None = None, quiet: bool = True,
        comm=MPI.COMM_WORLD):
    """Run one scene; returns the summary with the checks below, and the simulation."""
    contact = scenes.make_method(method)
    if scene == "bars":
        settings = Settings(cfl=0.9, t_end=1.2e-4, out=out, output_every=20, quiet=quiet)
        sim = scenes.bar_impact_sized(settings, contact, n_striker=6, n_target=9, comm=comm)
    else:
        settings = Settings(cfl=0.9, t_end=6e-5, out=out, output_every=20, quiet=quiet)
        sim = scenes.nosed_striker(settings, contact, v0=20.0, hold_block=False, comm=comm)
    summary = sim.run(extra=checks)
    return summary, sim


# ## What the run reports
#
# Momentum (no support, no load: it stays constant), the largest committed
# penetration, the pivoting's iterations (FILM, DME), the contact force peak
# and, for the bars, the mean contact stress over the middle 80 % of the
# contact against rho c0 v0 / 2 and the bars' final mean velocities.
def checks(sim) -> dict:
    e, h = sim.energy.data(), sim.history.data()
    p = e["momentum_z"]
    c = sim.contacts[0]
    out = {"method": c.method.name, "n_slaves": c.n, "bandwidth": int(c.bw),
           "momentum_error_rel": float(np.max(np.abs(p - p[0])) / abs(p[0])),
           "contact_force_max": float(h["contact_force"].max()),
           "iterations_max": c.method.info.get("iterations_max", 0)}
    if "momentum_z_striker" in e and "target" in sim.body_mass:
        dt = sim.settings.dt
        on = np.flatnonzero(h["n_active"] > 0)
        t0, T = on[0] * dt, 2 * L / C0
        w = (h["time"] > t0 + 0.1 * T) & (h["time"] < t0 + 0.9 * T)
        out["stress_over_rho_c0_v0_half"] = float(h["contact_force"][w].mean() / (math.pi * A ** 2)
                                                  / (RHO * C0 * V0_BARS / 2))
        out["velocity_striker_final"] = float(e["momentum_z_striker"][-1] / sim.body_mass["striker"])
        out["velocity_target_final"] = float(e["momentum_z_target"][-1] / sim.body_mass["target"])
    return out


@user_errors
def main(argv=None):
    parser = argparse.ArgumentParser(description="Node-to-segment contact on non-matching faces.")
    parser.add_argument("--scene", choices=("bars", "nose"), default="bars")
    parser.add_argument("--method", choices=("penalty", "film", "dme"), default="dme")
    parser.add_argument("--out", default=None, help="output directory")
    parser.add_argument("--quiet", action="store_true", help="no progress line")
    args = parser.parse_args(argv)
    out = args.out or f"results/nts_{args.scene}_{args.method}"
    s, sim = run(args.scene, args.method, out, quiet=args.quiet)
    if MPI.COMM_WORLD.rank == 0:
        print(f"node_to_segment {args.scene} ({s['method']}): {s['n_dofs']} dofs, {s['n_slaves']} "
              f"slaves (bandwidth of S {s['bandwidth']}), {s['n_steps']} steps on "
              f"{s['n_ranks']} rank(s)")
        print(f"max penetration {s['contact']['max_penetration']:.3e} m, momentum error "
              f"{s['momentum_error_rel']:.1e}, energy balance error "
              f"{s['energy_balance_error_rel']:.1e}, pivoting iterations <= {s['iterations_max']}")
        if "stress_over_rho_c0_v0_half" in s:
            print(f"contact stress / (rho c0 v0 / 2) = {s['stress_over_rho_c0_v0_half']:.5f}; final "
                  f"velocities striker {s['velocity_striker_final']:.4f}, target "
                  f"{s['velocity_target_final']:.4f} m/s (v0 = {V0_BARS})")
        else:
            print(f"peak contact force {s['contact_force_max']:.4g} N")
        print(f"results in {out}/")


if __name__ == "__main__":
    main()
