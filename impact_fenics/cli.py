"""The command line: run a scene file, render the fields of a finished run.

    impact-fenics run scenes/bar_impact.toml [--method film] [--out DIR] [--quiet]
    impact-fenics check scenes/bar_impact.toml [--method film] [--out DIR]
    impact-fenics plot results/bar_impact [--times 1e-4 2e-4] [--field sigma_zz] [--scale 50]
    impact-fenics shpb results/shpb [--dispersion]
    impact-fenics --version

(or ``python -m impact_fenics ...``). ``run`` works under mpirun; ``check`` reads and
checks the scene as ``run`` does before it meshes (the values, their plausibility,
the output directory, the estimate and the memory and disk it needs), writes
nothing and builds nothing but what a count needs (a mesh file is read). Exit codes:
0 done; 2 bad input, reported in one line "error: ..." before anything is
written (an output directory that is not a run directory, or that another run
is writing, is bad input); 3 the run diverged (one line with the step and the
stable dt; the output directory keeps what was written); 128 + the signal
number when SIGINT or SIGTERM stopped the program (before the run: nothing is
written; during or after it: the output directory is complete up to there).
"""
from __future__ import annotations

import argparse
import os
import sys

from .errors import InputError, UnstableRunError, user_errors


class _Parser(argparse.ArgumentParser):
    """argparse that reports a bad command line as one InputError line (exit 2)."""

    def error(self, message: str):
        raise InputError(f"{self.prog}: {message}")


def _parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="impact-fenics",
                     description="Explicit axisymmetric dynamics with node-to-node contact.")
    parser.add_argument("--version", action="version", version=f"impact-fenics {version()}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="{run,check,plot,shpb}")
    run = sub.add_parser("run", help="run a scene file (TOML)",
                         description="Run a scene file; results go to one directory.")
    check = sub.add_parser("check", help="check a scene file without running it",
                           description="Read and check a scene file as run does before it "
                                       "meshes, print the estimate; writes nothing.")
    for p in (run, check):
        p.add_argument("scene", help="the scene file, e.g. scenes/bar_impact.toml")
        p.add_argument("--method", choices=("penalty", "film", "dme"),
                       help="contact method for every [[contact]] (overrides the file)")
        p.add_argument("--out", help="output directory (overrides [output] dir; default "
                                     "results/<scene name>)")
        p.add_argument("--force", action="store_true",
                       help="run what the checks refuse: dt above the stable limit, a penalty "
                            "above its stable bound, a run estimated beyond the memory or "
                            "the free disk")
    run.add_argument("--quiet", action="store_true",
                     help="no progress line and no report (errors are still printed)")
    plot = sub.add_parser("plot", help="render a field of a finished run (PNG files)",
                          description="Render a field of RUN_DIR/fields.xdmf on the deformed "
                                      "mesh at chosen times; PNG files go to RUN_DIR.")
    plot.add_argument("run_dir", help="a run directory (holding fields.xdmf)")
    plot.add_argument("--times", nargs="+", type=float, metavar="T",
                      help="times in s (the nearest output times are used; default: four "
                           "spread over the run)")
    plot.add_argument("--field", default="sigma_zz",
                      help="sigma_rr, sigma_zz, sigma_tt, sigma_rz, von_mises, displacement "
                           "or velocity (default sigma_zz)")
    plot.add_argument("--scale", type=float,
                      help="displacement magnification (default: 1 for a finite-strain "
                           "run, its true shape; else the largest displacement shows as 5 %% "
                           "of the model size)")
    plot.add_argument("--region", nargs=4, type=float, metavar=("R0", "R1", "Z0", "Z1"),
                      help="frame the cells of r in [R0, R1], z in [Z0, Z1] (m, undeformed); "
                           "default: frame where the field is; --whole shows the whole model "
                           "(r to the right, z up in every picture)")
    plot.add_argument("--whole", action="store_true", help="show the whole model")
    shpb = sub.add_parser("shpb", help="the Hopkinson bar analysis of a finished SHPB run",
                          description="Separate the waves of a finished SHPB run's gauges, "
                                      "run the 1-, 2- and 3-wave analyses; shpb.csv and "
                                      "the pictures go to RUN_DIR (docs/shpb.md).")
    shpb.add_argument("run_dir", help="a run directory of an SHPB scene (scene.toml, "
                                      "history.csv)")
    shpb.add_argument("--dispersion", action="store_true",
                      help="correct each wave for the bars' Pochhammer-Chree dispersion")
    return parser


@user_errors
def main(argv: list[str] | None = None) -> int:
    """Entry point of ``impact-fenics`` and ``python -m impact_fenics``; returns the exit code."""
    args = _parser().parse_args(argv)
    if args.command == "run":
        return run_scene(args.scene, method=args.method, out=args.out, quiet=args.quiet,
                         force=args.force)
    if args.command == "check":
        return check_scene(args.scene, method=args.method, out=args.out, force=args.force)
    if args.command == "shpb":
        from .shpb.run_analysis import run_command

        return run_command(args.run_dir, dispersion=args.dispersion)
    region = None if args.whole else (tuple(args.region) if args.region else "auto")
    return plot_run(args.run_dir, field=args.field, times=args.times, scale=args.scale,
                    region=region)


def version() -> str:
    """The installed version of impact_fenics."""
    from importlib import metadata

    try:
        return metadata.version("impact_fenics")
    except metadata.PackageNotFoundError:
        return "(not installed: pip install -e .)"


def _checked(path: str, method: str | None, out: str | None, force: bool, quiet: bool,
             running: bool = True):
    """Read and check the scene, its output directory, its plausibility and its estimate
    (printed unless ``quiet``), as a run does before it meshes: (scene, output directory).
    ``running``: a run follows (it says when it will compile kernels first)."""
    from mpi4py import MPI

    from . import interrupts

    with interrupts.whole():  # the compiled modules a run needs (dolfinx, PETSc, numba)
        from . import meshing, plausibility, scene_file, simulation  # noqa: F401
    if running:
        meshing.start_gmsh()

    comm = MPI.COMM_WORLD
    if out is not None and not out.strip():
        raise InputError("--out '': the output directory name is empty")
    scene = scene_file.read_scene(path)
    if method:
        scene.set_method(method)
    if force:
        scene.force = True
    out_dir = os.path.expanduser(out or scene.output["dir"] or os.path.join("results", scene.stem))
    where = ("--out" if out else "[output] dir =" if scene.output["dir"] else
             "the default output directory (results/<scene file's name>)")
    scene_file.check_output_dir(out_dir, where, comm)
    plausibility.warn_implausible(scene, comm)
    if scene.mesh.generator == "shpb":
        from .shpb.run_analysis import bar_length_warning, bar_stress_warning

        for warning in (bar_stress_warning(scene), bar_length_warning(scene)):
            if warning and comm.rank == 0:
                print(warning, file=sys.stderr, flush=True)
    scene_file.check_resources(scene, comm, quiet, out_dir, running)
    return scene, out_dir


def check_scene(path: str, method: str | None = None, out: str | None = None,
                force: bool = False) -> int:
    """Check the scene file as :func:`run_scene` does before it meshes and print the
    estimate; nothing is built (but a mesh file read for its counts) or written."""
    from mpi4py import MPI

    _checked(path, method, out, force, quiet=False, running=False)
    if MPI.COMM_WORLD.rank == 0:
        print(f"{path}: checked (the mesh's groups and the stable step are checked when "
              "the run builds the mesh)", flush=True)
    return 0


def run_scene(path: str, method: str | None = None, out: str | None = None,
              quiet: bool = False, force: bool = False) -> int:
    """Check the scene file in full, build it, run it; returns the exit code."""
    from mpi4py import MPI

    from . import scene_file

    comm = MPI.COMM_WORLD
    scene, out_dir = _checked(path, method, out, force, quiet)
    sim = scene_file.build(scene, {"out": out_dir, "quiet": quiet}, comm)
    try:
        summary = sim.run(extra=lambda s: _scene_checks(s, scene.path))
    except UnstableRunError as exc:
        raise UnstableRunError(f"{exc}; the output so far is in {_where(sim, out_dir)}") from None
    if comm.rank == 0 and not quiet:
        _report(scene.title, summary, _shown(sim, out_dir))
    if scene.mesh.generator == "shpb" and sim.status.startswith("completed"):
        from .shpb.run_analysis import run_command

        try:  # the run is complete: an analysis it cannot make costs it nothing
            run_command(_shown(sim, out_dir), quiet=quiet)
        except InputError as exc:
            if comm.rank == 0:
                print(f"warning: the run is complete, its SHPB analysis was not made: "
                      f"{exc}", file=sys.stderr, flush=True)
    if comm.rank == 0 and sim.status.startswith("completed ("):
        print(f"warning: {sim.status}", file=sys.stderr, flush=True)
    at = f"step {summary['stopped_at_step']} of {summary['n_steps']}"
    t_end = getattr(sim.step_policy, "t_end", None)
    if t_end is not None and not sim.integrator.step.constant:  # the steps are not known
        at = (f"step {summary['stopped_at_step']}, t = {1e6 * sim.integrator.t:.5g} us of "
              f"{1e6 * t_end:.5g} us")
    return _exit_code(sim, at, out_dir, comm)


def _exit_code(run, at: str, out_dir: str, comm) -> int:
    """0, or 128 + the signal that stopped ``run`` (a Simulation, stopped
    ``at`` a step) after one line on rank 0."""
    from . import interrupts

    if not run.signal:
        return 0
    if comm.rank == 0:
        if run.status.startswith("interrupted"):
            what = f"run {run.status} at {at}; the output so far is in {_where(run, out_dir)}"
        else:
            what = (f"interrupted by {interrupts.name(run.signal)} after the last step; "
                    f"the run is complete in {_where(run, out_dir)}")
        print(f"stopped: {what}", file=sys.stderr, flush=True)
    return 128 + run.signal


def _shown(run, out_dir: str) -> str:
    """Where ``run`` (a Simulation) published its directory, said as the
    user gave ``out_dir`` (without the final separator)."""
    from .rundir import expand

    went = getattr(run, "out_dir", None) or expand(out_dir)
    return out_dir.rstrip(os.sep) + went[len(expand(out_dir)):] if went.startswith(
        expand(out_dir)) else went


def _where(run, out_dir: str) -> str:
    """``_shown(run, out_dir)/``, and, when the run went beside a complete run (it did not
    complete: ``DIR.interrupted``, ``DIR.diverged``), that the complete run is kept."""
    shown = _shown(run, out_dir)
    if shown == out_dir.rstrip(os.sep) or not shown.startswith(out_dir.rstrip(os.sep) + "."):
        return f"{shown}/"
    return f"{shown}/ (the complete run in {out_dir.rstrip(os.sep)}/ is kept)"


def _scene_checks(sim, scene_path: str) -> dict:
    """Summary entries of any scene: the scene file and the contact duration (s)."""
    extra = {"scene_file": scene_path}
    figures = getattr(sim, "scene_figures", None)  # a finite-strain bar's shape
    if figures is not None:
        extra.update(figures(sim))
    contact = sim.summary.get("contact")
    if contact is not None:
        first, last = contact["first_contact_step"], contact["last_contact_step"]
        if first is None:
            extra["contact_duration"] = 0.0
        elif sim.integrator.step.constant:
            extra["contact_duration"] = (last - first + 1) * sim.settings.dt
        else:  # a varying step: between the history's first and last rows with contact
            rows = [c for c in sim.summary.get("impact", [])
                    if c.get("first_contact_time") is not None]
            if rows:
                extra["contact_duration"] = (max(c["last_contact_time"] for c in rows)
                                             - min(c["first_contact_time"] for c in rows))
    return extra


def _report(title: str, s: dict, out_dir: str) -> None:
    """A few lines on rank 0 after the run."""
    steps = (f"{s['dt_range'][0]:.4g} to {s['dt_range'][1]:.4g} s to t = {s['t_end']:.6g} s"
             if "dt_range" in s else f"{s['dt']:.4g} s")
    print(f"{title}: {s['status']}, {s['stopped_at_step']} of {s['n_steps']} steps of "
          f"{steps} (stable limit {s['dt_critical']:.4g} s), {s['n_dofs']} dofs on "
          f"{s['n_ranks']} rank(s), {s['wall_time']:.1f} s")
    from .report import console_lines, energy_line

    if "final_length" in s:  # a finite-strain bar
        # the node that started at (R, 0): a Taylor bar's impact face, a billet's foot
        face = ("x of the corner at y = 0" if s.get("geometry", {}).get("kind")
                == "plane_strain" else "radius of the face z = 0")
        plastic = any("plastic_work" in b for b in s.get("bodies", {}).values())
        print(f"shape: length {s['final_length'] * 1e3:.4f} mm, {face} "
              f"{s['final_face_radius'] * 1e3:.4f} mm"
              + (f", max eps_p {s['eps_p_max']:.4f}" if plastic else ""))

    if "energy" in s:
        print(energy_line(s))
    if "contact" in s:
        c = s["contact"]
        first, last = c["first_contact_step"], c["last_contact_step"]
        span = (f"active from step {first} to {last}"
                + (f" ({s['contact_duration'] * 1e6:.1f} us)" if "contact_duration" in s else "")
                if first is not None else "never active")
        repaired = (f", re-paired every {c['repair_every']} step(s) ({c['repairs']} times)"
                    if "repair_every" in c else "")
        if c["method"] == "tie":
            print(f"tie: {c['n_constraints']} tied nodes")
        else:
            print(f"contact ({c['method']}): {c['n_constraints']} constraints, {span}, "
                  f"max penetration {c['max_penetration']:.3g} m{repaired}")
    for line in console_lines(s):
        print(line)
    print(_results_line(out_dir, f"impact-fenics plot {out_dir} renders it"))


def _results_line(out_dir: str, hint: str) -> str:
    """Where the results are (``out_dir`` as the user gave it): with fields.xdmf written,
    open it in ParaView (and ``hint``); without (``[output] fields = false``), the files
    the run wrote instead."""
    try:
        names = sorted(n for n in os.listdir(os.path.expanduser(out_dir))
                       if not n.startswith("."))
    except OSError:
        names = []
    if "fields.xdmf" in names:
        return f"results in {out_dir}/ (open fields.xdmf in ParaView; {hint})"
    return (f"results in {out_dir}/: {', '.join(names)} (no fields.xdmf: [output] fields = "
            "false)")


def plot_run(run_dir: str, field: str = "sigma_zz", times: list[float] | None = None,
             scale: float | None = None, region="auto") -> int:
    """Render ``field`` of a finished run at ``times`` (s) into PNG files (rank 0)."""
    from mpi4py import MPI

    from . import plotting, rundir

    run_dir = os.path.expanduser(run_dir)
    if not os.path.isdir(run_dir):
        raise InputError(f"run directory '{run_dir}' does not exist")
    if times:
        _check_plot_times(run_dir, times)
    if MPI.COMM_WORLD.rank == 0:
        paths = plotting.render_fields(run_dir, field, times, scale, region=region)
        rundir.record_files(run_dir, paths)  # the pictures go with the run they show
        for path in paths:
            print(path)
    return 0


def _check_plot_times(run_dir: str, times: list[float]) -> None:
    """--times must lie within the run's output times (its summary: 0 to t_end, s)."""
    import json

    try:
        with open(os.path.join(run_dir, "summary.json")) as f:
            summary = json.load(f)
        t_end = (float(summary["t_end"]) if summary.get("strain") == "finite"
                 else float(summary["stopped_at_step"]) * float(summary["dt"]))
    except (OSError, ValueError, KeyError, TypeError):
        return  # no summary: render_fields reports what is missing
    for t in times:
        if not 0.0 <= t <= t_end * (1 + 1e-9):
            raise InputError(f"--times {t:g}: outside the run, which covers 0 to {t_end:.6g} s")
