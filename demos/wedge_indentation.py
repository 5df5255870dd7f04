# # A wedge bit into rock, in plane strain
#
# A chisel or a wedge bit is long along its edge: its blow on rock is a plane-strain
# problem, modelled by its section. This demo strikes a steel wedge of 90 degrees
# (a round tip of 0.5 mm, 10 mm high) at 10 m/s into a Drucker-Prager granite, and
# reads the blow's force-penetration curve and the plastic zone it leaves under the
# tip (scenes/wedge_rock.toml; docs/plane_strain.md).
#
#     scripts/mpirun.sh -n 2 .venv/bin/python demos/wedge_indentation.py
#     .venv/bin/python demos/wedge_indentation.py --method film --out results/wedge_film
#
# It writes the run's directory (history.csv with the contact force and the tip's
# displacement u_y, fields.xdmf with eps_p_eq and yielded, to open in ParaView) and
# force_penetration.png there.

import argparse
import os

import numpy as np
from dolfinx.mesh import compute_midpoints
from mpi4py import MPI

from impact_fenics import rundir, scene_file
from impact_fenics.errors import user_errors

# ## The scene
#
# The half section x >= 0 with `symmetry = "x=0"` (u_x = 0 on x = 0, and node to
# segment's rules at a tip on that plane), a slab t = 0.01 m thick: every force,
# mass and energy below is that of the half slab (a full wedge's force per metre
# is 2 F / t).
#
# The wedge: steel, linear elastic (E = 200 GPa, nu = 0.3), P1 triangles of
# 0.5 mm, moving down at 10 m/s at t = 0 with its tip touching the rock's top at
# the origin (`[bodies.wedge] velocity`): one blow, its kinetic energy ½ m v² =
# 0.204 J per half slab the whole budget.
#
# The rock: the granite of scenes/bit_rock.toml (E = 60 GPa, nu = 0.25,
# UCS 200 MPa, tensile strength 10 MPa, friction angle 50 deg, dilatancy 10 deg),
# its Drucker-Prager cone matched to Mohr-Coulomb in plane strain
# (`match = "plane_strain"`, docs/plane_strain.md section 4: the compression
# meridian's cone would overstate the strength by a factor of several at 50 deg).
# A block 30 mm x 20 mm (the half), P1 triangles of 0.25 mm, free: the waves
# reach its bottom and come back in 2 x 20 mm / 5.26 km/s = 7.6 us, so the
# curve after that is the block's, not a half-space's; what the blow does to the
# rock under the tip happens before.
#
# Contact: node to segment (DME by default), the wedge's face (the tip's arc and
# the flank) the master, the rock's top under it the slaves; frictionless.
SCENE = os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir, "scenes",
                     "wedge_rock.toml")


def run(method: str | None = None, out: str | None = None, t_end: float | None = None,
        quiet: bool = True, comm: MPI.Comm = MPI.COMM_WORLD, scene: str = SCENE):
    """Run the blow on ``comm``; returns the summary (with :func:`blow_checks`) and the
    simulation. ``t_end`` (s) shortens it (a test's run)."""
    sc = scene_file.read_scene(scene)
    if method is not None:
        sc.set_method(method)
    overrides = {"out": out, "quiet": quiet, "plots": out is not None}
    if t_end is not None:
        overrides.update(t_end=t_end, n_steps=None)
    sim = scene_file.build(sc, overrides, comm=comm)
    return sim.run(extra=blow_checks), sim


# ## What the run reports
#
# The penetration is the tip's depth below the rock's original top, -u_y of the
# wedge at its tip (the probe `tip_u_y`); the contact force the sum of the
# slaves' normal forces (N, per half slab). The curve's key figures: the peak
# force and the penetration there, the largest penetration, and the impulse
# sum F dt, which is the wedge's loss of momentum (nothing else acts on it).
#
# The plastic zone is the set of rock cells whose equivalent plastic strain at the
# end (`eps_p_eq`, the cell's mean over its points, a field of fields.xdmf) is at
# least the rock's elastic strain at its uniaxial strength, UCS / E = 3.3e-3: the
# rock crushed under the tip. (The cells with any yield, `yielded`, reach much
# farther: the stress wave leaving the tip at some GPa yields the rock in shear
# wherever it passes with little confinement, to a strain of a few 1e-3 at most.)
# Its depth is the lowest centroid of those cells below the original top, its half
# width the farthest one from the plane of symmetry. A centroid is a cell's, not a
# rank's: the figures are the same however the mesh is split.
CRUSHED = 200e6 / 60e9  # UCS / E of the rock (-)


def plastic_zone(sim, eps_p: float = CRUSHED) -> tuple[float, float]:
    """The plastic zone's depth and half width (m): the largest -y and x of the centroids
    of the cells with eps_p_eq >= ``eps_p`` (0, 0 without one). Collective."""
    msh = sim.model.mesh
    eps_p_eq = sim.cell_fields()["eps_p_eq"]
    cells = np.flatnonzero(eps_p_eq >= eps_p).astype(np.int32)
    centres = compute_midpoints(msh, 2, cells) if cells.size else np.zeros((0, 3))
    depth = float(-centres[:, 1].min(initial=0.0))
    width = float(centres[:, 0].max(initial=0.0))
    return (sim.comm.allreduce(depth, op=MPI.MAX), sim.comm.allreduce(width, op=MPI.MAX))


def blow_checks(sim) -> dict:
    h = sim.history.data()
    force, penetration = h["contact_force"], -h["tip_u_y"]
    k = int(np.argmax(force))
    depth, width = plastic_zone(sim)
    return {
        "force_peak": float(force[k]),
        "penetration_at_force_peak": float(penetration[k]),
        "time_force_peak": float(h["time"][k]),
        "penetration_max": float(penetration.max()),
        "contact_impulse": float(np.sum(force * h["dt"])),
        "plastic_zone_depth": depth,
        "plastic_zone_half_width": width,
    }


# ## The force-penetration curve
def plot(sim, path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    h = sim.history.data()
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
    ax1.plot(-h["tip_u_y"] * 1e3, h["contact_force"] / 1e3)
    ax1.set_xlabel("penetration of the tip (mm)")
    ax1.set_ylabel("contact force (kN, per half slab of 0.01 m)")
    ax1.set_title("force-penetration")
    ax2.plot(h["time"] * 1e6, h["contact_force"] / 1e3)
    ax2.set_xlabel("time (us)")
    ax2.set_ylabel("contact force (kN)")
    ax2.set_title("the blow")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


@user_errors
def main(argv=None):
    parser = argparse.ArgumentParser(description="A wedge bit into Drucker-Prager rock "
                                                 "(plane strain).")
    parser.add_argument("--method", choices=("film", "dme"), default=None,
                        help="the contact method (default the scene's, dme)")
    parser.add_argument("--out", default="results/wedge_indentation", help="output directory")
    parser.add_argument("--t-end", type=float, default=None, help="end time (s)")
    parser.add_argument("--quiet", action="store_true", help="no progress line")
    args = parser.parse_args(argv)
    s, sim = run(args.method, args.out, t_end=args.t_end, quiet=args.quiet)
    if MPI.COMM_WORLD.rank == 0:
        picture = os.path.join(sim.out_dir, "force_penetration.png")
        plot(sim, picture)
        rundir.record_files(sim.out_dir, [picture])
        print(f"wedge_indentation: {s['n_cells']} cells, {s['n_dofs']} dofs, {s['n_steps']} "
              f"steps of {s['dt']:.4g} s, {s['n_ranks']} rank(s)")
        print(f"peak force {s['force_peak']:.10g} N (per half slab) at {s['time_force_peak'] * 1e6:.4g}"
              f" us, penetration there {s['penetration_at_force_peak'] * 1e3:.6g} mm; largest "
              f"penetration {s['penetration_max'] * 1e3:.6g} mm; impulse {s['contact_impulse']:.6g} N s")
        print(f"plastic zone: depth {s['plastic_zone_depth'] * 1e3:.10g} mm, half width "
              f"{s['plastic_zone_half_width'] * 1e3:.10g} mm (centroids of the cells of eps_p_eq >= UCS / E)")
        print(f"energy balance error {s['energy_balance_error_rel']:.1e}; results in {args.out}/")


if __name__ == "__main__":
    main()
