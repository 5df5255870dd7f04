# # The split Hopkinson pressure bar, simulated and analysed
#
# A steel striker (0.2 m, 10 m/s) hits the incident bar; a J2 specimen (10 mm x 5 mm,
# sigma_y = 300 MPa, H = 1 GPa) sits between the incident and the transmitter bar (20 mm,
# linear elastic, nu = 0.29); a strain gauge on each bar records the incident, reflected
# and transmitted waves. The scene is scenes/shpb.toml (the sizing rule of its cells,
# steps and bar lengths is in docs/shpb.md); this demo runs it, analyses the gauges with
# and without the Pochhammer-Chree dispersion correction, and prints how far the
# recovered stress-strain curves are from the specimen's own law.
#
#     scripts/mpirun.sh -n 2 .venv/bin/python demos/shpb.py [--out DIR] [--shaped]
#
# --shaped runs scenes/shpb_shaped.toml instead: the same test with a pulse shaper (a
# compliant striker interface), whose slow rise does not shake the specimen; its face
# forces stay within about 1 % of the law (docs/shpb.md, "Why the face forces ring").
#
# Results go to results/shpb_demo/ (or --out DIR): the run's files, and shpb.csv with
# shpb_waves.png, shpb_stress_strain.png and shpb_equilibrium.png from the analysis
# (the same as `impact-fenics shpb DIR`).

import argparse
import os

import numpy as np
from mpi4py import MPI

from impact_fenics import cli
from impact_fenics.errors import user_errors
from impact_fenics.shpb.run_analysis import analyse_run, columns

SCENES = os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir, "scenes")


# ## The run
#
# `impact-fenics run` checks the scene, warns when rho c0 v / 2 nears the bars' yield
# stress, runs the four bodies with three contact sets (the striker on the incident bar
# node to node, the specimen's faces node to segment) and ends with the analysis.
def run(out: str, shaped: bool = False) -> None:
    scene = os.path.join(SCENES, "shpb_shaped.toml" if shaped else "shpb.toml")
    code = cli.main(["run", scene, "--out", out, "--quiet"])
    if code:
        raise SystemExit(code)


# ## The recovered curve against the law
#
# On the plateau (the equilibrium ratio R <= 5 % and the 3-wave strain rate within 10 %
# of its median there), each curve against the specimen's law in uniaxial stress at
# that rate: the truth (the faces' contact forces at the strain of the faces'
# displacements), the 1-wave, the 2-wave and the 3-wave analyses.
def errors(out: str, dispersion: bool) -> list[str]:
    r = analyse_run(out, dispersion)
    c, p = columns(r), r.plateau
    from impact_fenics.shpb.run_analysis import material_law

    def line(name: str, stress: np.ndarray, strain: np.ndarray) -> str:
        law = material_law(r.setup.specimen_material, strain[p], r.rate)
        rel = stress[p] / law - 1.0
        return (f"  {name:<8} mean {np.mean(rel):+.2%}, largest {np.max(np.abs(rel)):.2%}")

    head = (f"{'with' if dispersion else 'without'} the dispersion correction: plateau of "
            f"{int(p.sum())} samples at {r.rate:.0f} 1/s, 3-wave strain "
            f"{c['strain_3'][p].min():.3f} to {c['strain_3'][p].max():.3f}")
    rows = [head, line("1-wave", c["stress_1"], c["strain_1"]),
            line("2-wave", c["stress_2"], c["strain_3"]),
            line("3-wave", c["stress_3"], c["strain_3"])]
    if "strain_true" in c and "stress_true" in c:
        rows.append(line("truth", c["stress_true"], c["strain_true"]))
    return rows


@user_errors
def main() -> int:
    parser = argparse.ArgumentParser(description="Run scenes/shpb.toml (or shpb_shaped.toml) and compare the recovered curves with the law.")
    parser.add_argument("--out", default=None, help="results/shpb_demo (or shpb_shaped_demo)")
    parser.add_argument("--shaped", action="store_true",
                        help="run scenes/shpb_shaped.toml (a shaped pulse) instead")
    args = parser.parse_args()
    args.out = args.out or os.path.join("results", "shpb_shaped_demo" if args.shaped
                                        else "shpb_demo")
    run(args.out, args.shaped)
    if MPI.COMM_WORLD.rank == 0:
        for dispersion in (False, True):
            for row in errors(args.out, dispersion):
                print(row)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
