# # The Taylor bar: a copper cylinder hits a rigid wall at 227 m/s
#
# The classic large-deformation benchmark of explicit codes (Taylor 1948; Simo
# 1992; Zienkiewicz et al. 1998): a copper bar, L = 32.4 mm, R = 3.2 mm, moving
# at 227 m/s onto a frictionless rigid wall; J2 plasticity at finite strain
# with linear hardening (E = 117 GPa, nu = 0.35, rho = 8930 kg/m^3,
# sigma_y = 400 MPa, H = 100 MPa), 80 us. The bar mushrooms: its impact face
# spreads from 3.2 mm to about 7.2 mm and it shortens to about 21.4 mm.
#
#     scripts/mpirun.sh -n 2 .venv/bin/python demos/taylor_bar.py --n-r 8
#
# The model: axisymmetric, Q1 quadrilaterals with mean dilatation (the
# locking-free element, impact_fenics/internal_force/finite.py), the
# Hencky/exponential-map J2 (materials/finite_j2.py), the rigid wall by FILM
# or DME (contact/plane.py), the step re-estimated every 10 steps from the
# current cells (stepping.FollowingStep), all through the one loop
# (impact_fenics.scenes.taylor_bar builds the Simulation).
#
# The impact face, two ways (`--face`): `contact` (default) makes every boundary
# node a unilateral contact candidate, so the rim of the impact face may lift
# off the wall, and does; `held` keeps the nodes of the impact face on the wall
# (u_z = 0, free to slide radially), the condition under which the converged
# literature values were computed (Simo 1992 keeps nodes that reach the wall on
# it; Foulk et al. 2021 fix u_z on the impact face), the rest of the boundary
# still in unilateral contact. docs/taylor_bar.md compares the two.
#
# Results: RUN_DIR/history.csv,
# RUN_DIR/summary.json, RUN_DIR/history.png, RUN_DIR/fields.xdmf (displacement,
# Cauchy stress, eps_p_eq, temperature per cell; Warp By Vector at scale 1).

import argparse

import numpy as np
from mpi4py import MPI

from impact_fenics.errors import require, user_errors
from impact_fenics.materials.finite_j2 import FiniteJ2
from impact_fenics.scenes import taylor_bar
from impact_fenics.simulation import Settings

# ## The scene
LENGTH, RADIUS = 32.4e-3, 3.2e-3  # m
V0 = 227.0  # m/s, toward the wall (-z)
T_END = 80e-6  # s
COPPER = FiniteJ2(E=117e9, nu=0.35, density=8930.0, yield_stress=400e6, hardening=100e6)
FACES = ("contact", "held")


def read_scene(path: str) -> dict:
    """The scene's values (scenes/taylor_bar.toml), checked as `impact-fenics run` checks them."""
    from impact_fenics import scene_file

    sc = scene_file.read_scene(path)
    require(sc.finite and sc.wall is not None and sc.time["dt"] is None,
            f"scene '{path}': the demo needs a finite-strain body, a [wall] and [time] cfl")
    m, body, t = sc.materials[sc.bodies[0].material], sc.bodies[0], sc.time
    require(m.model == "j2", f"scene '{path}': the demo runs a j2 material")
    return {"mesh": dict(sc.mesh.params),
            "material": {"E": m.E, "nu": m.nu, "density": m.density,
                         "yield_stress": m.yield_stress, "hardening": m.hardening},
            "body": {"velocity": list(body.velocity)}, "wall": {"z": sc.wall.z, "method": sc.wall.method},
            "time": {"t_end": t["t_end"], "safety": t["cfl"], "dt_interval": t["dt_interval"] or 10}}


def run(n_r: int = 4, method: str = "film", safety: float = 0.5, out: str | None = None,
        comm=MPI.COMM_WORLD, scene: dict | None = None, face: str = "contact") -> dict:
    """The Taylor bar on an n_r x (10 n_r) mesh (square cells), or as ``scene`` (a
    :func:`read_scene` dict) says; ``face`` 'contact' (unilateral, the rim may lift off)
    or 'held' (u_z = 0 on the impact face, the literature's condition). Returns the summary."""
    require(face in FACES, f"face = '{face}': use one of {', '.join(FACES)}")
    radius, length, material, v0, z_wall, interval = RADIUS, LENGTH, COPPER, V0, 0.0, 10
    t_end = T_END
    if scene is not None:
        m, t = scene["mesh"], scene["time"]
        radius, length, n_r = float(m["radius"]), float(m["length"]), int(m["n_r"])
        material = FiniteJ2(**{k: float(v) for k, v in scene["material"].items()})
        v0 = -float(scene["body"]["velocity"][1])
        require(float(scene["body"]["velocity"][0]) == 0.0, "[body] velocity: v_r must be 0")
        z_wall, method = float(scene["wall"]["z"]), str(scene["wall"]["method"])
        t_end, safety, interval = float(t["t_end"]), float(t["safety"]), int(t["dt_interval"])
    require(n_r >= 1, f"n_r = {n_r}: must be >= 1")
    require(z_wall == 0.0, f"[wall] z = {z_wall} m: the demo's wall is the plane z = 0")
    n_z = max(1, round(n_r * length / radius))
    settings = Settings(history_every=20, out=out, quiet=out is None, plots=out is not None,
                        fields=out is not None, output_every=1000)
    bar = taylor_bar(settings, material, radius, length, n_r, v0, method, face, t_end,
                     cfl=safety, dt_interval=interval, comm=comm)
    figures = bar.scene_figures

    def checks(sim) -> dict:
        """The demo's entries of summary.json, written with the run's own."""
        import math
        # the mass and the initial kinetic energy against their closed forms
        mass = material.density * math.pi * radius ** 2 * length
        # held: the face's nodes stop at t = 0 (their u_z fixed, their velocity zeroed), an
        # impact loss 1/2 m_face v0^2 outside the run's ledger, which starts from the rest
        xy, u = sim.model.node_xy[: sim.model.n_owned // 2], sim.integrator.u_owned
        m_face = 0.0
        if face == "held":
            held = np.flatnonzero(np.abs(xy[:, 1]) <= 1e-9 * length)
            m_face = float(np.sum(sim.integrator.mass[2 * held + 1]))
        # the length also as the largest z of the free end face (some references measure that)
        top = np.abs(xy[:, 1] - length) <= 1e-9 * length
        z_top = float(np.max(xy[top, 1] + u[1::2][top])) if top.any() else -np.inf
        return {**figures(sim), "initial_kinetic_closed_form": 0.5 * mass * v0 ** 2,
                "impact_face_loss": comm.allreduce(0.5 * m_face * v0 ** 2),
                "final_length_max": comm.allreduce(z_top, op=MPI.MAX),
                "mesh": f"{n_r} x {n_z}", "method": method, "face": face}

    return bar.run(extra=checks)


@user_errors
def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--n-r", type=int, default=4, help="cells across the radius (10x along the bar)")
    p.add_argument("--method", choices=("film", "dme"), default="film")
    p.add_argument("--face", choices=FACES, default="contact",
                   help="impact face in unilateral contact (default) or held on the wall "
                        "(the literature's condition)")
    p.add_argument("--scene", default=None, help="a scene file (scenes/taylor_bar.toml)")
    p.add_argument("--out", default=None)
    a = p.parse_args(argv)
    scene = read_scene(a.scene) if a.scene else None
    n_r = scene['mesh']['n_r'] if scene else a.n_r
    out = a.out or f"results/taylor_bar_{n_r}" + ("_held" if a.face == "held" else "")
    s = run(a.n_r, a.method, out=out, scene=scene, face=a.face)
    if MPI.COMM_WORLD.rank == 0:
        # ## The check serial and parallel runs share
        print(f"Taylor bar, mesh {s['mesh']}, {s['method']}, impact face {s['face']}, "
              f"{s['n_steps']} steps (dt {s['dt_range'][0]:.3g}..{s['dt_range'][1]:.3g} s)")
        note = "" if s["face"] == "held" else "; they hold the face: --face held"
        print(f"  final length      {s['final_length'] * 1e3:.4f} mm   (literature 21.42-21.48)")
        print(f"  impact-face radius {s['final_face_radius'] * 1e3:.4f} mm   "
              f"(literature 7.22-7.23{note})")
        if s["face"] == "held":
            print(f"  impact-face loss at t = 0 (1/2 m_face v0^2) {s['impact_face_loss']:.4f} J")
        print(f"  max eps_bar_p     {s['eps_p_max']:.4f}")
        e = s["energy"]
        print(f"  energies (J): initial kinetic {s['energy_initial']:.4f} "
              f"(closed form {s['initial_kinetic_closed_form']:.4f}), plastic "
              f"{s['plastic_work']:.3f}, stored {s['stored_elastic']:.3f}, kinetic "
              f"{e['kinetic']:.3f}, wall activation {e['activation_loss']:.3f}")
        print(f"  kinetic identity (relative) {s['energy_balance_error_rel']:.2e}; "
              f"work_gap (booked internal work - stored - plastic, O(dt^2)) "
              f"{e['work_gap']:.4f} J")


if __name__ == "__main__":
    main()
