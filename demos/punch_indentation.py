# # A rigid punch indenting an elastic block (paper Section 3.1)
#
# A flat rigid punch of radius R_z, modelled as a single node of mass 0.1 kg
# with only a z dof, is driven into an axisymmetric steel block by the force
# -sigma(t) pi R_z^2, sigma a trapezoid of 200 MPa (up over 10 us, held, down
# between 90 and 100 us). Every surface node with r <= R_z is tied to the punch
# by a unilateral constraint: 107, 308 or 610 constraints for R_z = 1, 3, 6 m
# (the paper's Sim1, Sim2 and Sim3). The block mesh (about 22,600 CST
# elements) has a surface spacing near 1 cm out to 6 m and coarsens with depth.
#
#     scripts/mpirun.sh -n 2 .venv/bin/python demos/punch_indentation.py --method dme --radius 6
#     scripts/mpirun.sh -n 2 .venv/bin/python demos/punch_indentation.py --method film --film-solver dense
#
# With a single light punch node every constraint couples to every other
# through the punch: FILM must solve a coupled system (here exactly, in
# O(n log n), or by dense factorisation as the paper did), DME moves the active
# nodes with the punch as one rigid cluster.

import argparse

from mpi4py import MPI

from impact_fenics import scenes
from impact_fenics.errors import user_errors
from impact_fenics.simulation import Settings

DT = 3.64e-7  # s, the paper's step
N_STEPS = 400  # 1.456e-4 s


def run(method: str, out: str | None, radius: float = 1.0, film_solver: str = "fast",
        penalty="scaled", dt: float = DT, n_steps: int = N_STEPS, block: dict | None = None,
        output_every: int = 20, quiet: bool = True, comm=MPI.COMM_WORLD):
    """Run the indentation; returns the summary (with the punch checks) and the simulation."""
    contact = scenes.make_method(method, penalty=penalty, film_solver=film_solver)
    settings = Settings(dt=dt, n_steps=n_steps, out=out, output_every=output_every, quiet=quiet)
    sim = scenes.punch_indentation(settings, contact, radius=radius, block=block, comm=comm)
    return sim.run(extra=punch_checks), sim


# ## What the run reports
#
# The punch displacement history (history.csv, column punch_u, negative is
# into the block), the contact force on the punch (punch_force), and the
# contact CPU time per step split into detection, solve and update.
def punch_checks(sim) -> dict:
    h = sim.history.data()
    c = sim.contacts[0]
    return {
        "method": c.method.name,
        "n_constraints": c.n,
        "punch_displacement_max": float(-h["punch_u"].min()),
        "punch_force_max": float(h["punch_force"].max()),
        "max_penetration": sim.summary["contact"]["max_penetration"],
        "radius": float(c.r.max()),
    }


@user_errors
def main(argv=None):
    parser = argparse.ArgumentParser(description="A rigid punch indenting an elastic block.")
    parser.add_argument("--method", choices=("penalty", "film", "dme"), default="dme")
    parser.add_argument("--radius", type=int, choices=(1, 3, 6), default=1,
                        help="punch radius R_z (m): 107, 308 or 610 constraints")
    parser.add_argument("--film-solver", choices=("fast", "dense"), default="fast")
    parser.add_argument("--penalty", default="scaled",
                        help="penalty stiffness in N/m, 'auto' or 'scaled' (stability)")
    parser.add_argument("--out", default=None, help="output directory")
    parser.add_argument("--quiet", action="store_true", help="no progress line")
    args = parser.parse_args(argv)
    out = args.out or f"results/punch_{args.method}_R{args.radius}"
    s, _ = run(args.method, out, radius=scenes.PUNCH_RADII[args.radius],
               film_solver=args.film_solver, penalty=args.penalty, quiet=args.quiet)
    if MPI.COMM_WORLD.rank == 0:
        print(f"punch_indentation ({s['method']}, R_z = {args.radius} m): {s['n_constraints']} "
              f"constraints, {s['n_cells']} cells, {s['n_dofs']} dofs, {s['n_ranks']} rank(s)")
        print(f"punch displacement max {s['punch_displacement_max'] * 1e3:.4f} mm, contact force max "
              f"{s['punch_force_max'] / 1e6:.1f} MN, max penetration {s['max_penetration']:.2e} m")
        print(f"contact CPU {s['contact_cpu_time_per_step_median'] * 1e6:.1f} us/step, whole step "
              f"{s['step_time_median'] * 1e6:.1f} us (medians)")
        print(f"results in {out}/")


if __name__ == "__main__":
    main()
