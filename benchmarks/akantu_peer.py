"""A peer figure: Akantu's explicit lumped-mass step, in its own process and venv.

Akantu (https://akantu.ch, ``pip install akantu``) is installed into a separate
venv (never into the project's .venv), e.g.

    /usr/bin/python3 -m venv /tmp/akantu-venv && /tmp/akantu-venv/bin/pip install akantu

The harness (impact_fenics.bench, part "akantu") writes our plane-strain mesh's nodes
and triangles with :func:`write_msh` (plain text, no gmsh: the same nodes in the same
order and the same cells), an initial velocity per node (.npy) and a time step, and
runs this file with the Akantu interpreter:

    /tmp/akantu-venv/bin/python benchmarks/akantu_peer.py --mesh bar.msh \
        --velocity v0.npy --dt 1e-6 --check-steps 10 --steps 30 --out a.json

The model: plane strain (Akantu's 2D), P1 triangles (one quadrature point each),
SolidMechanicsModel with _explicit_lumped_mass (central differences: the internal
forces element by element at the points every step), no boundary condition, u = 0 and
the given velocity at t = 0, the given dt. It first advances ``check_steps`` steps and
saves u (the physics check: the harness advances the same problem with ours), then
times blocks of ``steps`` solveStep() calls. The figure is wall time per step per dof.
Only the standard library at import: the harness imports :func:`write_msh`.
"""
from __future__ import annotations

import argparse
import json
import os
import time

MATERIALS = {
    "elastic": """model solid_mechanics_model [
  material elastic [
    name = steel
    rho = {rho}
    E = {E}
    nu = {nu}
    Plane_Stress = false
  ]
]
""",
    # J2 with linear isotropic hardening (radial return); sigma_y and h (Pa) filled in
    "j2": """model solid_mechanics_model [
  material plastic_linear_isotropic_hardening [
    name = steel
    rho = {rho}
    E = {E}
    nu = {nu}
    sigma_y = {sigma_y}
    h = {hardening}
    Plane_Stress = false
  ]
]
""",
}


def write_msh(path: str, nodes, triangles) -> None:
    """A gmsh 2.2 ASCII file of ``nodes`` (n, 2) in m and ``triangles`` (m, 3) (0-based
    node indices, written counter-clockwise), node i tagged i + 1, every triangle in
    physical group 1 ("bar"): Akantu reads the nodes in this order."""
    with open(path, "w") as f:
        f.write("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n")
        f.write('$PhysicalNames\n1\n2 1 "bar"\n$EndPhysicalNames\n')
        f.write(f"$Nodes\n{len(nodes)}\n")
        for i, (x, y) in enumerate(nodes):
            f.write(f"{i + 1} {float(x)!r} {float(y)!r} 0\n")
        f.write(f"$EndNodes\n$Elements\n{len(triangles)}\n")
        for k, (a, b, c) in enumerate(triangles):
            (xa, ya), (xb, yb), (xc, yc) = nodes[a], nodes[b], nodes[c]
            if (xb - xa) * (yc - ya) - (xc - xa) * (yb - ya) < 0.0:
                b, c = c, b
            f.write(f"{k + 1} 2 2 1 1 {a + 1} {b + 1} {c + 1}\n")
        f.write("$EndElements\n")


def _yielded_fraction(model, aka) -> float | None:
    """The fraction of the points whose equivalent plastic strain is > 0 (None if this
    Akantu does not expose it)."""
    try:
        eps = model.getMaterial(0).getInternalReal("iso_hardening")(aka._triangle_3)
    except Exception:
        return None
    return float((eps > 0).mean()) if eps.size else None


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--mesh", required=True)
    p.add_argument("--velocity", required=True, help=".npy of (n_nodes, 2) m/s at t = 0")
    p.add_argument("--dt", type=float, required=True, help="the time step (s)")
    p.add_argument("--check-steps", type=int, default=10)
    p.add_argument("--steps", type=int, default=30)
    p.add_argument("--repeats", type=int, default=3, help="timed blocks (0: the check alone)")
    p.add_argument("--out", required=True)
    p.add_argument("--material", choices=sorted(MATERIALS), default="elastic")
    p.add_argument("--label", default="", help="names u_akantu_<label>.npy (default: material)")
    p.add_argument("--E", type=float, default=2e11, help="Young's modulus (Pa)")
    p.add_argument("--nu", type=float, default=0.3)
    p.add_argument("--rho", type=float, default=7850.0, help="density (kg/m^3)")
    p.add_argument("--yield-stress", type=float, default=250e6, help="j2: sigma_y (Pa)")
    p.add_argument("--hardening", type=float, default=2e9, help="j2: h (Pa)")
    args = p.parse_args()

    import numpy as np
    import akantu as aka

    here = os.path.dirname(os.path.abspath(args.out))
    material = os.path.join(here, f"material_{args.material}.dat")
    with open(material, "w") as f:
        f.write(MATERIALS[args.material].format(
            rho=repr(args.rho), E=repr(args.E), nu=repr(args.nu),
            sigma_y=repr(args.yield_stress), hardening=repr(args.hardening)))
    t0 = time.perf_counter()
    aka.parseInput(material)
    mesh = aka.Mesh(2)
    mesh.read(args.mesh)
    model = aka.SolidMechanicsModel(mesh)
    model.initFull(_analysis_method=aka._explicit_lumped_mass)
    stable = float(model.getStableTimeStep())
    model.setTimeStep(args.dt)
    n_nodes = mesh.getNbNodes()
    v0 = np.load(args.velocity)
    if v0.shape != (n_nodes, 2):
        raise SystemExit(f"error: velocity {v0.shape} for {n_nodes} nodes")
    model.getDisplacement()[:, :] = 0.0
    model.getVelocity()[:, :] = v0
    setup = time.perf_counter() - t0
    for _ in range(args.check_steps):
        model.solveStep()
    u_check = np.array(model.getDisplacement(), copy=True)
    np.save(os.path.join(here, f"u_akantu_{args.label or args.material}.npy"), u_check)
    yielded = _yielded_fraction(model, aka) if args.material == "j2" else None
    samples = []
    for _ in range(args.repeats):
        t = time.perf_counter()
        for _ in range(args.steps):
            model.solveStep()
        samples.append((time.perf_counter() - t) / args.steps)
    step = float(np.median(samples)) if samples else None  # --repeats 0: the check alone
    n_dofs = 2 * n_nodes
    n_elements = int(mesh.getNbElement(type=aka._triangle_3))
    n_points = int(model.getFEEngine().getNbIntegrationPoints(aka._triangle_3))
    rec = {"version": getattr(aka, "__version__", "?"), "n_nodes": n_nodes, "n_dofs": n_dofs,
           "n_elements": n_elements, "points_per_element": n_points,
           "dt": args.dt, "stable_dt": stable, "check_steps": args.check_steps,
           "steps": args.steps, "repeats": args.repeats, "step_seconds": step,
           "samples": samples, "setup_seconds": setup,
           "ns_per_dof_per_step": None if step is None else 1e9 * step / n_dofs,
           "ns_per_point_per_step": (None if step is None
                                     else 1e9 * step / (n_elements * n_points)),
           "yielded_fraction": yielded,
           "omp_num_threads": os.environ.get("OMP_NUM_THREADS"),
           "material": args.material,
           "model": "plane strain, P1 triangles, explicit lumped mass (central differences)"}
    with open(args.out, "w") as f:
        json.dump(rec, f, indent=1)


if __name__ == "__main__":
    main()
