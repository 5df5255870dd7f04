# # The Taylor bar on a rough anvil: Coulomb friction on the finite-strain wall
#
# The copper Taylor bar of scenes/taylor_bar.toml (227 m/s, 80 us, face = "contact")
# with [wall] friction = 0, 0.1, 0.2, 0.5 and "stick", FILM or DME. Prints per μ the
# foot radius (the largest current r of a boundary node within h = R / n_r of the
# anvil at the end), the contact radius (the outermost node in contact), the face
# radius (the node that started at (R, 0)), the length and the slip work D, and
# draws the lower profiles (the impact face, then the side) at the end.
#
#     .venv/bin/python demos/taylor_rough_anvil.py --n-r 8 --figure docs/figures/taylor_rough_anvil.png
#
# docs/taylor_bar.md and docs/friction.md give the figures.

import argparse
import pathlib
import tempfile

import numpy as np
from mpi4py import MPI

from impact_fenics.contact.plane import boundary_nodes, contact_radius, foot_radius
from impact_fenics.errors import user_errors
from impact_fenics.scene_file import build, read_scene

SCENE = pathlib.Path(__file__).resolve().parent.parent / "scenes" / "taylor_bar.toml"
MUS = ("0.0", "0.1", "0.2", "0.5", '"stick"')


def run(method: str, friction: str, n_r: int, comm: MPI.Comm = MPI.COMM_WORLD) -> dict:
    """One run: the radii (m), length (m), D (J) and the lower profile (current (r, z) of
    the face nodes by R, then of the side nodes r = R by Z, m) on rank 0."""
    text = SCENE.read_text().replace('method = "film"', f'method = "{method}"\nfriction = '
                                     f"{friction}").replace("n_r = 8", f"n_r = {n_r}")
    with tempfile.TemporaryDirectory() as tmp:
        path = pathlib.Path(comm.bcast(tmp if comm.rank == 0 else None)) / "scene.toml"
        if comm.rank == 0:
            path.write_text(text)
        comm.Barrier()
        scene = read_scene(str(path))
        comm.Barrier()
    sim = build(scene, {"out": None, "quiet": True, "plots": False, "fields": False}, comm)
    s = sim.run(extra=sim.scene_figures)
    model = sim.model
    u = sim.integrator.u_owned
    radius = scene.mesh.params["radius"]
    h = radius / n_r
    xy = model.node_xy[: model.n_owned // 2]
    now = xy + u.reshape(-1, 2)
    tol = 1e-9 * scene.mesh.params["length"]
    face = np.abs(xy[:, 1]) <= tol
    side = np.abs(xy[:, 0] - radius) <= tol
    parts = comm.gather((xy[face, 0], now[face], xy[side, 1], now[side]))
    nodes = boundary_nodes(model.V, model.n_owned // 2)
    friction = s.get("friction", [{}])[0]
    out = {"foot": foot_radius(nodes, model.node_xy, u, scene.wall.z, h, comm),
           "contact": contact_radius(sim.contacts[-1], model.node_xy, u, comm),
           "face": s["final_face_radius"], "length": s["final_length"],
           "slip_work": friction.get("slip_work", 0.0),
           "identity": s["energy_balance_error_rel"]}
    if comm.rank == 0:
        f_key = np.concatenate([p[0] for p in parts])
        f_now = np.concatenate([p[1] for p in parts])[np.argsort(f_key)]
        s_key = np.concatenate([p[2] for p in parts])
        s_now = np.concatenate([p[3] for p in parts])[np.argsort(s_key)]
        out["profile"] = np.vstack([f_now, s_now[1:]])  # (the corner once)
    return out


@user_errors
def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--n-r", type=int, default=4)
    parser.add_argument("--method", choices=("film", "dme"), default="film")
    parser.add_argument("--figure", default=None, help="the profiles' picture (png)")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    results = {}
    for mu in MUS:
        r = results[mu] = run(args.method, mu, args.n_r, comm)
        if comm.rank == 0:
            print(f"{args.method} n_r = {args.n_r} mu = {mu.strip(chr(34))}: foot "
                  f"{r['foot'] * 1e3:.4f} mm, contact {r['contact'] * 1e3:.4f} mm, face "
                  f"{r['face'] * 1e3:.4f} mm, length {r['length'] * 1e3:.4f} mm, D "
                  f"{r['slip_work']:.4g} J, identity {r['identity']:.2g}", flush=True)
    if args.figure and comm.rank == 0:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(7, 4.5))
        for mu, r in results.items():
            p = r["profile"] * 1e3
            ax.plot(p[:, 0], p[:, 1], marker=".", ms=3, label=f"μ = {mu.strip(chr(34))}")
        ax.set_xlabel("r (mm)")
        ax.set_ylabel("z (mm)")
        ax.set_aspect("equal")
        ax.set_ylim(-0.2, 6.0)  # the foot: the rest of the side hardly depends on μ
        ax.set_xlim(0.0, None)
        ax.set_title(f"Taylor bar at 80 µs, {args.method.upper()}, n_r = {args.n_r}")
        ax.legend(loc="upper right")
        fig.tight_layout()
        fig.savefig(args.figure, dpi=120)


if __name__ == "__main__":
    main()
