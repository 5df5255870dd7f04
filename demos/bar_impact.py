# # Longitudinal impact of two thick bars (paper Section 3.2)
#
# Two coaxial steel cylinders of radius a = 0.1 m touch at z = 0: the striker
# (0.80 m, below) moves at v0 = 5 m/s toward the resting target (0.85 m).
# Their contact faces carry six nodes each, paired node to node. The contact
# is enforced by penalty, FILM or DME, chosen on the command line:
#
#     scripts/mpirun.sh -n 2 .venv/bin/python demos/bar_impact.py --method film
#     scripts/mpirun.sh -n 2 .venv/bin/python demos/bar_impact.py --method dme --restitution 0
#     scripts/mpirun.sh -n 2 .venv/bin/python demos/bar_impact.py --method penalty --penalty 1.19e10
#
# Results go to results/bar_impact_<method>/ (or --out DIR): fields.xdmf for
# ParaView, history.csv (sigma_zz at r = 0.1 m, z = 0.2 m in the target; the
# contact force and gaps), contact_pairs.h5 (gap, force and active flag of each
# pair), energy.csv and summary.json.

import argparse

import numpy as np
from mpi4py import MPI

from impact_fenics import scenes
from impact_fenics.errors import user_errors
from impact_fenics.simulation import Settings

# ## The scene
#
# Element size 0.02 m (five intervals across the radius), nu = 0.3, dt = 1 us,
# 500 us of impact: the 1D estimate of the contact time is 2 L / c0 = 317 us
# for the shorter striker; the three-dimensional waves lengthen it.
V0 = 5.0  # m/s
DT = 1e-6  # s
T_END = 5e-4  # s


def run(method: str, out: str | None, penalty="scaled", restitution: float = 0.0,
        positions: str = "mass_weighted", h: float = 0.02, nu: float = 0.3, dt: float = DT,
        t_end: float = T_END, striker_length: float = 0.8, target_length: float = 0.85,
        structured: bool = False, output_every: int = 25, quiet: bool = True,
        comm=MPI.COMM_WORLD):
    """Run the impact; returns the summary (with the contact checks) and the simulation."""
    contact = scenes.make_method(method, penalty=penalty, restitution=restitution,
                                 positions=positions)
    settings = Settings(dt=dt, t_end=t_end, out=out, output_every=output_every, quiet=quiet)
    sim = scenes.bar_impact(settings, contact, h=h, nu=nu, v0=V0, striker_length=striker_length,
                            target_length=target_length, structured=structured, comm=comm)
    summary = sim.run(extra=impact_checks)
    return summary, sim


# ## What the run reports
#
# Momentum: no external force acts, so the total z momentum stays m_s v0.
# Contact duration: from the first to the last step with an active pair.
# After separation each bar's mean velocity (its momentum over its mass).
def impact_checks(sim) -> dict:
    e = sim.energy.data()
    p = e["momentum_z"]
    p0 = sim.body_mass["striker"] * V0
    c = sim.contacts[0]
    first = sim.summary["contact"]["first_contact_step"]
    last = sim.summary["contact"]["last_contact_step"]
    duration = (last - first + 1) * sim.settings.dt if first is not None else 0.0
    return {
        "method": c.method.name,
        "n_pairs": c.n,
        "momentum_error_rel": float(np.max(np.abs(p - p0)) / abs(p0)),
        "contact_duration": duration,
        "velocity_striker_final": float(e["momentum_z_striker"][-1] / sim.body_mass["striker"]),
        "velocity_target_final": float(e["momentum_z_target"][-1] / sim.body_mass["target"]),
        "max_penetration": sim.summary["contact"]["max_penetration"],
        "v0": V0,
    }


@user_errors
def main(argv=None):
    parser = argparse.ArgumentParser(description="Longitudinal impact of two thick bars.")
    parser.add_argument("--method", choices=("penalty", "film", "dme"), default="film")
    parser.add_argument("--penalty", default="scaled",
                        help="penalty stiffness in N/m, 'auto' (paper) or 'scaled' (stability)")
    parser.add_argument("--restitution", type=float, default=0.0, help="DME restitution e in [0, 1]")
    parser.add_argument("--positions", choices=("mass_weighted", "paper"), default="mass_weighted",
                        help="DME pair positions: mass-weighted, or the paper's equal weights (eq. 9)")
    parser.add_argument("--h", type=float, default=0.02, help="element size (m)")
    parser.add_argument("--t-end", type=float, default=T_END, help="end time (s)")
    parser.add_argument("--out", default=None, help="output directory")
    parser.add_argument("--quiet", action="store_true", help="no progress line")
    args = parser.parse_args(argv)
    out = args.out or f"results/bar_impact_{args.method}"
    summary, sim = run(args.method, out, penalty=args.penalty, restitution=args.restitution,
                       positions=args.positions, h=args.h, t_end=args.t_end, quiet=args.quiet)
    if MPI.COMM_WORLD.rank == 0:
        s = summary
        print(f"bar_impact ({s['method']}): {s['n_dofs']} dofs, {s['n_pairs']} pairs, "
              f"{s['n_steps']} steps of {s['dt']:.3g} s on {s['n_ranks']} rank(s)")
        print(f"contact duration {s['contact_duration'] * 1e6:.1f} us, max penetration "
              f"{s['max_penetration']:.3e} m, momentum error {s['momentum_error_rel']:.1e}")
        print(f"final mean velocities: striker {s['velocity_striker_final']:.4f} m/s, "
              f"target {s['velocity_target_final']:.4f} m/s (v0 = {V0} m/s)")
        print(f"energy balance error {s['energy_balance_error_rel']:.1e}; contact CPU "
              f"{s['contact_cpu_time_per_step_median'] * 1e6:.1f} us/step (median)")
        print(f"results in {out}/")


if __name__ == "__main__":
    main()
