# # A pressure pulse in a bar: the explicit scheme against the 1D wave
#
# A steel bar of radius 0.05 m and length 1 m, with Poisson's ratio set to
# zero, is loaded on its end z = 0 by a pressure pulse. With nu = 0 the
# axisymmetric continuum carries an exact one-dimensional wave: the pulse
# travels at c0 = sqrt(E / rho) with the stress sigma_zz = -p and the
# particle velocity v = p / (rho c0), so that sigma = -rho c0 v.
#
# Run it with
#
#     scripts/mpirun.sh -n 2 .venv/bin/python demos/elastic_wave.py --out results/elastic_wave
#
# and open results/elastic_wave/fields.xdmf in ParaView.

import argparse

import numpy as np
from mpi4py import MPI

from impact_fenics import scenes
from impact_fenics.errors import user_errors
from impact_fenics.probes import arrival_time
from impact_fenics.simulation import Settings

# ## The scene
#
# The bar (``scenes.elastic_bar``) is meshed with a structured grid of
# alternating diagonals, element size h. Its end z = 0 carries a trapezoid
# pressure of 100 MPa: up over 20 us, held to 100 us, down by 120 us. The rise
# spans 0.1 m of bar, twenty elements at the default h = 5 mm.
P0 = 100e6  # Pa
T_END = 1.5e-4  # s: the front is at 0.76 m, no reflection reaches the probes
STATIONS = (0.3, 0.6)  # z of the two probes (m), at r = 0.02 m
PROBE_R = 0.02


def run(out: str | None, h: float = 0.005, nu: float = 0.0, cfl: float = 0.9,
        quiet: bool = True, comm=MPI.COMM_WORLD) -> tuple[dict, object]:
    """Run the scene; returns the summary with the wave checks, and the simulation."""
    settings = Settings(cfl=cfl, t_end=T_END, out=out, output_every=40, quiet=quiet)
    sim = scenes.elastic_bar(settings, h=h, nu=nu, peak=P0, comm=comm)
    for k, z in enumerate(STATIONS):
        sim.add_probe(f"sigma_zz_{k}", (PROBE_R, z), "sigma_zz")
        sim.add_probe(f"u_z_{k}", (PROBE_R, z), "u_z")
    summary = sim.run(extra=wave_checks)
    return summary, sim


# ## The checks
#
# Arrival: the time at which sigma_zz in a probe cell first reaches half the
# plateau. The speed is the distance between the two probe cells (their
# midpoints) over the difference of their arrival times. Plateau: the mean
# stress and the mean velocity (the slope of u_z) while the held part of the
# pulse passes the first probe.
def wave_checks(sim) -> dict:
    material = next(iter(sim.model.bodies.values())).material
    c0 = material.bar_wave_speed()
    h = sim.history.data()
    t = h["time"]
    z_probe = sim.probes.midpoints[::2, 1]
    arrivals = [arrival_time(t, -h[f"sigma_zz_{k}"], 0.5 * P0) for k in range(2)]
    c_measured = (z_probe[1] - z_probe[0]) / (arrivals[1] - arrivals[0])
    window = (t > arrivals[0] + 3e-5) & (t < arrivals[0] + 7e-5)
    sigma = float(np.mean(h["sigma_zz_0"][window]))
    velocity = float(np.polyfit(t[window], h["u_z_0"][window], 1)[0])
    return {
        "wave_speed_exact": c0,
        "wave_speed_measured": c_measured,
        "wave_speed_error_rel": abs(c_measured - c0) / c0,
        "arrival_times": arrivals,
        "probe_z": z_probe.tolist(),
        "plateau_stress": sigma,
        "plateau_stress_exact": -P0,
        "plateau_velocity": velocity,
        "plateau_velocity_exact": P0 / (material.density * c0),
        "h": sim.model.tmesh.info["h"],
    }


@user_errors
def main(argv=None):
    parser = argparse.ArgumentParser(description="A pressure pulse in a nu = 0 bar.")
    parser.add_argument("--out", default="results/elastic_wave", help="output directory")
    parser.add_argument("--h", type=float, default=0.005, help="element size (m)")
    parser.add_argument("--nu", type=float, default=0.0, help="Poisson's ratio (0 for the 1D oracle)")
    parser.add_argument("--cfl", type=float, default=0.9, help="dt / stable dt of the element bound")
    parser.add_argument("--quiet", action="store_true", help="no progress line")
    args = parser.parse_args(argv)
    summary, sim = run(args.out, h=args.h, nu=args.nu, cfl=args.cfl, quiet=args.quiet)
    if MPI.COMM_WORLD.rank == 0:
        s = summary
        print(f"elastic_wave: {s['n_dofs']} dofs, {s['n_steps']} steps of {s['dt']:.4g} s "
              f"(stable limit {s['dt_critical']:.4g} s)")
        print(f"wave speed {s['wave_speed_measured']:.1f} m/s vs c0 = {s['wave_speed_exact']:.1f} m/s "
              f"(error {100 * s['wave_speed_error_rel']:.2f} %)")
        print(f"plateau sigma_zz = {s['plateau_stress'] / 1e6:.3f} MPa vs -p = {-P0 / 1e6:.3f} MPa; "
              f"v = {s['plateau_velocity']:.4f} m/s vs p/(rho c0) = {s['plateau_velocity_exact']:.4f} m/s")
        print(f"energy balance error {s['energy_balance_error_rel']:.1e} (relative)")


if __name__ == "__main__":
    main()
