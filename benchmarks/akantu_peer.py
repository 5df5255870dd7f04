"""A peer figure: Akantu's explicit lumped-mass step, in its own process and venv.

Akantu (https://akantu.ch, ``pip install akantu``) is installed into a separate
venv (never into the project's .venv), e.g.

    /usr/bin/python3 -m venv /tmp/akantu-venv && /tmp/akantu-venv/bin/pip install akantu

The harness (impact_fenics.bench, part "akantu") writes the mesh with
:func:`write_mesh` (gmsh, in the project's interpreter) and runs this file with
the Akantu interpreter:

    /tmp/akantu-venv/bin/python benchmarks/akantu_peer.py --mesh bar.msh --steps 30 --out a.json

The model: the same structured bar (0.5 m x 1 m, steel, P1 triangles) in plane
strain (Akantu's 2D; no axisymmetric hoop term), SolidMechanicsModel with
_explicit_lumped_mass (central differences: internal forces element by element
at the quadrature points every step), no boundary condition, a random initial
displacement. The figure is wall time per solveStep() per dof.
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
    rho = 7850
    E = 2e11
    nu = 0.3
    Plane_Stress = false
  ]
]
""",
    # J2 with linear isotropic hardening (radial return); sigma_y and h (Pa) filled in
    "j2": """model solid_mechanics_model [
  material plastic_linear_isotropic_hardening [
    name = steel
    rho = 7850
    E = 2e11
    nu = 0.3
    sigma_y = {sigma_y}
    h = {hardening}
    Plane_Stress = false
  ]
]
""",
}


def write_mesh(path: str, radius: float = 0.5, length: float = 1.0, h: float = 0.01) -> None:
    """The structured bar of impact_fenics.meshing.bar as a gmsh 2.2 file (run in the project's venv)."""
    from impact_fenics import meshing

    gmsh = meshing._gmsh()
    gmsh.model.add("akantu_bar")
    try:
        geo = gmsh.model.geo
        p = [geo.addPoint(0, 0, 0, h), geo.addPoint(radius, 0, 0, h),
             geo.addPoint(radius, length, 0, h), geo.addPoint(0, length, 0, h)]
        c = [geo.addLine(p[i], p[(i + 1) % 4]) for i in range(4)]
        s = geo.addPlaneSurface([geo.addCurveLoop(c)])
        geo.synchronize()
        n_r, n_z = max(1, round(radius / h)), max(1, round(length / h))
        for k in (0, 2):
            gmsh.model.mesh.setTransfiniteCurve(c[k], n_r + 1)
        for k in (1, 3):
            gmsh.model.mesh.setTransfiniteCurve(c[k], n_z + 1)
        gmsh.model.mesh.setTransfiniteSurface(s, "Alternate")
        gmsh.model.addPhysicalGroup(2, [s], 1)
        gmsh.model.setPhysicalName(2, 1, "bar")
        gmsh.model.mesh.generate(2)
        old = gmsh.option.getNumber("Mesh.MshFileVersion")
        gmsh.option.setNumber("Mesh.MshFileVersion", 2.2)
        gmsh.write(path)
        gmsh.option.setNumber("Mesh.MshFileVersion", old)
    finally:
        gmsh.model.remove()


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--mesh", required=True)
    p.add_argument("--steps", type=int, default=30)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--out", required=True)
    p.add_argument("--material", choices=sorted(MATERIALS), default="elastic")
    p.add_argument("--yield-stress", type=float, default=250e6, help="j2: sigma_y (Pa)")
    p.add_argument("--hardening", type=float, default=2e9, help="j2: h (Pa)")
    args = p.parse_args()

    import numpy as np
    import akantu as aka

    here = os.path.dirname(os.path.abspath(args.out))
    material = os.path.join(here, "material.dat")
    with open(material, "w") as f:
        f.write(MATERIALS[args.material].format(sigma_y=args.yield_stress,
                                                hardening=args.hardening))
    t0 = time.perf_counter()
    aka.parseInput(material)
    mesh = aka.Mesh(2)
    mesh.read(args.mesh)
    model = aka.SolidMechanicsModel(mesh)
    model.initFull(_analysis_method=aka._explicit_lumped_mass)
    model.setTimeStep(0.8 * model.getStableTimeStep())
    n_nodes = mesh.getNbNodes()
    u = model.getDisplacement()
    u[:, :] = 1e-6 * np.random.default_rng(5).standard_normal((n_nodes, 2))
    setup = time.perf_counter() - t0
    model.solveStep()  # warm-up
    samples = []
    for _ in range(args.repeats):
        t = time.perf_counter()
        for _ in range(args.steps):
            model.solveStep()
        samples.append((time.perf_counter() - t) / args.steps)
    step = float(np.median(samples))
    n_dofs = 2 * n_nodes
    rec = {"version": getattr(aka, "__version__", "?"), "n_nodes": n_nodes, "n_dofs": n_dofs,
           "n_elements": int(mesh.getNbElement(type=aka._triangle_3)),
           "steps": args.steps, "repeats": args.repeats, "step_seconds": step,
           "samples": samples, "setup_seconds": setup,
           "ns_per_dof_per_step": 1e9 * step / n_dofs,
           "omp_num_threads": os.environ.get("OMP_NUM_THREADS"),
           "material": args.material,
           "model": "plane strain, P1 triangles, explicit lumped mass (central differences)"}
    with open(args.out, "w") as f:
        json.dump(rec, f, indent=1)


if __name__ == "__main__":
    main()
