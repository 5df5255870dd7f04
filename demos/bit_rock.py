# # Bit-rock impact: one blow of percussive drilling
#
# A piston strikes a drill rod; the compressive wave it starts, F_i(t), runs down
# the rod to the bit, which is pressed into the rock. Part of the wave's energy
# goes into the rock, the rest is reflected back up the rod. This demo models
# the rod by its impedance alone (Lundberg 1982): with Z = rho c A the rod
# pushes the bit with F = 2 F_i - Z w (w the bit's downward velocity), and the
# reflected wave is F_r = F_i - Z w. The bit is a rigid body with one z dof;
# the rock an axisymmetric block under it.
#
#     scripts/mpirun.sh -n 2 .venv/bin/python demos/bit_rock.py
#     scripts/mpirun.sh -n 2 .venv/bin/python demos/bit_rock.py --method film --button 0.02
#
# The run reports the bit's force-penetration curve (force_penetration.png), the
# wave energies (incident, reflected, delivered to the bit), the energy left in
# the rock, and the efficiency: work done on the rock / incident energy.

import argparse
import math
import os

import numpy as np
from mpi4py import MPI

from impact_fenics import loads, rundir, scenes
from impact_fenics.errors import InputError, user_errors
from impact_fenics.materials import DruckerPrager
from impact_fenics.simulation import Settings

# ## The scene
#
# Rock: granite-like, E = 60 GPa, nu = 0.25, rho = 2600 kg/m^3 (Jaeger, Cook & Zimmerman, *Fundamentals of Rock Mechanics*, 4th ed.
# 2007, give E = 50-70 GPa and nu = 0.2-0.3 for intact granites). For the
# Drucker-Prager rock: uniaxial compressive strength 200 MPa, tensile strength
# 10 MPa (Westerly granite is near both), friction angle 50 deg
# (intact granite 45-60 deg from Hoek-Brown fits, Hoek & Brown 1997, matched on
# the compression meridian), dilatancy 10 deg (a fifth of it, as is usual for
# rock, Vermeer & de Borst 1984), no hardening.
#
# Rod and blow: a steel rod of 32 mm diameter, Z = rho c0 A = 31.9e3 kg/s;
# the incident wave of a piston of the rod's impedance striking at about 9 m/s:
# a trapezoid of 150 kN (Z v/2), rising over 10 us, 80 us long (a piston of
# about 0.2 m). Bit: 0.5 kg, a flat face of radius 10 mm (or a spherical
# button of radius R_s, `--button R_s`), touching the rock at t = 0.
#
# Domain: a wave leaving the bit comes back to it after 2 L / c_L, so a block of
# radius and depth L = a + 1.05 c_L t_end / 2 (c_L = 5262 m/s: 0.42 m for
# 150 us) keeps every echo off the bit until t_end, and no larger one changes
# the bit's response. The mesh (meshing.punch_block) has a/10 under the face and
# grows by 0.05 m/m with the distance from it.
GRANITE_DP = dict(E=60e9, nu=0.25, density=2600.0, ucs=200e6, tensile_strength=10e6,
                  friction_angle=50.0, dilatancy_angle=10.0)
T_END = 1.5e-4  # s: the blow (80 us) and the bit's rebound off the rock
INCIDENT = loads.Trapezoid(peak=150e3, t_rise=1e-5, t_fall=7e-5, t_end=8e-5)  # N


def rock_material(kind: str):
    """The rock: 'elastic' (LinearElastic) or 'drucker_prager' (path-dependent, its state
    at the quadrature points of the stiffness rule)."""
    if kind == "elastic":
        return scenes.GRANITE
    return DruckerPrager(**GRANITE_DP)


def run(method: str = "dme", rock: str = "elastic", out: str | None = None,
        button: float | None = None, t_end: float = T_END, h_surface: float | None = None,
        quiet: bool = True, comm=MPI.COMM_WORLD):
    """Run one blow; returns the summary (with the checks below) and the simulation."""
    settings = Settings(cfl=0.9, t_end=t_end, out=out, output_every=100, quiet=quiet)
    sim = scenes.bit_rock(settings, scenes.make_method(method), rock=rock_material(rock),
                          button_radius=button, incident=INCIDENT, h_surface=h_surface,
                          comm=comm)
    return sim.run(extra=blow_checks), sim


# ## What the run reports
#
# The wave energies are booked by the bit every step (RigidBody: incident
# sum dt F_i^2/Z, reflected sum dt F_r^2/Z, delivered sum dt F w); they balance
# to round-off. The rock's energy at the end is the ledger's kinetic and strain
# energy of the block (and its plastic work, when the rock is plastic); as the
# bit has left the rock by then, it is the work done on the rock. The area
# under the force-penetration curve, the work of the contact force on the bit's
# displacement, is a second measure of it: summed in the ledger's form (the force
# of a step times the step's mean velocity) it equals the rock's energy to
# round-off for FILM and DME, whose active face nodes move with the bit; a plain
# trapezoid over the sampled curve misses it by O(dt) (about 3 % here: the light
# bit's velocity changes by a few % a step).
PLASTIC_KEYS = ("plastic_work", "plastic_dissipation")


def blow_checks(sim) -> dict:
    h = sim.history.data()
    bit = sim.contacts[0].rigid
    last = sim.energy.data()
    v = h["bit_v"]
    kinetic_bit = 0.5 * bit.mass * v[-2] * v[-1]  # the ledger's 1/2 m v^n v^{n+1}
    rock = last["kinetic"][-1] - kinetic_bit + last["strain"][-1]
    rock += sum(float(last[k][-1]) for k in PLASTIC_KEYS if k in last)
    penetration, force = -h["bit_u"], h["bit_force"]
    # the contact force of step n times the step's mean downward velocity (the ledger's form)
    w = -np.concatenate([[0.0], v])  # the bit starts at rest
    work_curve = float(np.sum(force * sim.settings.dt * 0.5 * (w[:-1] + w[1:])))
    k = int(np.argmax(penetration))
    return {
        "wave_incident": bit.wave_incident,
        "wave_reflected": bit.wave_reflected,
        "wave_delivered": bit.wave_delivered,
        "wave_balance_error_rel": abs(bit.wave_incident - bit.wave_reflected
                                      - bit.wave_delivered) / bit.wave_incident,
        "rock_energy": float(rock),
        "work_force_penetration": work_curve,
        "efficiency": float(rock) / bit.wave_incident,
        "penetration_max": float(penetration[k]),
        "force_at_max_penetration": float(force[k]),
        "force_max": float(force.max()),
        "contact_ended": bool(h["n_active"][-1] == 0),
    }


# ## The force-penetration curve
#
# Beside it the static stiffness of the same mesh (statics.rigid_indentation:
# the face nodes held at a rigid u_z = -delta, one direct solve): at maximum
# penetration, where the bit stops, the dynamic F/delta is close to it
# (tests/test_bit_rock.py shows it tends to it as the blow slows down).
def static_stiffness(sim) -> float:
    """K_h (N/m) of a flat face on elastic rock; NaN for a button (its flat limit is no
    reference) and for a plastic rock (no stiffness is assembled; its elastic K_h would
    be the curve's initial slope only)."""
    if sim.contacts[0].b.any() or sim.integrator.K is None:
        return float("nan")
    return scenes.static_stiffness(sim)


def plot(sim, path: str, k_static: float) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    h = sim.history.data()
    bit = sim.contacts[0].rigid
    dt = sim.settings.dt
    t = np.concatenate([[0.0], h["time"]])
    v = np.concatenate([[0.0], h["bit_v"]])
    f_i = np.array([bit.incident(x) for x in t[:-1]])
    f_r = f_i + bit.impedance * 0.5 * (v[:-1] + v[1:])  # F_i - Z w, w = -v averaged
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
    pen = -h["bit_u"] * 1e3
    ax1.plot(pen, h["bit_force"] / 1e3, label="contact force on the bit")
    if math.isfinite(k_static):
        d = np.linspace(0.0, pen.max(), 2)
        ax1.plot(d, k_static * d * 1e-3 / 1e3, "--", label=f"static K_h = {k_static:.3g} N/m")
    ax1.set_xlabel("penetration (mm)")
    ax1.set_ylabel("force (kN)")
    ax1.legend()
    ax1.set_title("force-penetration")
    ax2.plot(t[:-1] * 1e6, f_i / 1e3, label="incident F_i")
    ax2.plot(t[:-1] * 1e6, f_r / 1e3, label="reflected F_r")
    ax2.plot(h["time"] * 1e6, h["bit_force"] / 1e3, label="contact")
    ax2.set_xlabel("time (us)")
    ax2.set_ylabel("force (kN, compressive > 0)")
    ax2.legend()
    ax2.set_title(f"waves in the rod (dt = {dt:.3g} s)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


@user_errors
def main(argv=None):
    parser = argparse.ArgumentParser(description="One blow of percussive drilling.")
    parser.add_argument("--method", choices=("penalty", "film", "dme"), default="dme")
    parser.add_argument("--rock", choices=("elastic", "drucker_prager"), default="elastic")
    parser.add_argument("--button", type=float, default=None,
                        help="spherical button radius R_s (m); default a flat face")
    parser.add_argument("--out", default=None, help="output directory")
    parser.add_argument("--quiet", action="store_true", help="no progress line")
    args = parser.parse_args(argv)
    out = args.out or f"results/bit_rock_{args.rock}_{args.method}"
    s, sim = run(args.method, args.rock, out, button=args.button, quiet=args.quiet)
    k_static = static_stiffness(sim)
    comm = MPI.COMM_WORLD
    if comm.rank == 0:
        picture = os.path.join(sim.out_dir, "force_penetration.png")
        plot(sim, picture, k_static)
        rundir.record_files(sim.out_dir, [picture])  # the run's own, replaced with it
        print(f"bit_rock ({args.method}, {args.rock} rock): {s['n_cells']} cells, "
              f"{s['n_dofs']} dofs, {s['n_steps']} steps of {s['dt']:.4g} s, {s['n_ranks']} rank(s)")
        print(f"waves (J): incident {s['wave_incident']:.6f}, reflected {s['wave_reflected']:.6f}, "
              f"delivered to the bit {s['wave_delivered']:.6f} (balance {s['wave_balance_error_rel']:.1e})")
        print(f"rock energy {s['rock_energy']:.6f} J (force-penetration work "
              f"{s['work_force_penetration']:.6f} J), contact ended: {s['contact_ended']}")
        print(f"efficiency (work on the rock / incident) = {s['efficiency']:.6f}")
        print(f"max penetration {s['penetration_max'] * 1e3:.6f} mm at F = "
              f"{s['force_at_max_penetration'] / 1e3:.4f} kN: F/delta = "
              f"{s['force_at_max_penetration'] / s['penetration_max']:.5g} N/m, static K_h "
              f"{k_static:.5g} N/m")
        print(f"energy balance error {s['energy_balance_error_rel']:.1e}; results in {out}/")


if __name__ == "__main__":
    main()
