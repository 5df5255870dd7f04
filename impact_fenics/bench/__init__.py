"""The benchmark harness: where the time of a step goes, and how far it is from the floor.

    python -m impact_fenics.bench            # the full run (< 10 min on 2 cores)
    python -m impact_fenics.bench --quick    # about a minute
    python -m impact_fenics.bench --smoke    # seconds (the test suite runs this)
    scripts/mpirun.sh -n 2 .venv/bin/python -m impact_fenics.bench --parts scaling,stream

It prints tables and writes every raw median to ``results/bench.json`` (``--out``).
Parts (``--parts``, comma separated; all by default), and the module of each:

step      ns per dof per step of the same update done three ways, in one run:   step.py
          the integrator (predict + advance) and the Simulation loop without
          outputs; a bare MatMult (and MatMultAdd, VecAXPY) on the same matrix;
          a SciPy CSR loop (v += A u; u += dt v) on the same matrix.
contact   contact time per step (detection / solve / update) against the number  contact.py
          of constraints, for a rigid punch and for node pairs, per method.
solvers   FILM's solve_fast (numba) and solve_dense (numpy, LAPACK) alone on      contact.py
          synthetic gaps, against an empty numba call with the same arguments.
friction  the contact step at Sim3 (the punch, 610 constraints) with mu = 0 and    contact.py
          mu = 0.3, per method, in one run, with the load average.
scaling   step and MatMult time per dof from ~20k to ~1M dofs.                    scaling.py
stream    a STREAM-like bandwidth (VecCopy, VecAXPY, VecWAXPY, VecDot) in GB/s.   scaling.py
ranks     the scaling and stream parts again on 2 ranks (launched with            scaling.py
          scripts/mpirun.sh), the speed-up of 2 ranks over 1 and the bandwidth ratio.
format    AIJ against BAIJ (block size 2) for MatMult and the whole step.         matrix_format.py
matfree   a compiled matrix-free CST internal force (benchmarks/matfree_cst.py)   peers.py
          against MatMult.
finite    the finite-strain J2 step against the small-strain J2 step and the      finite.py
          linear step, with where its time goes.
taylor    the Taylor bar's whole run in element-steps per second, 1 and 2 ranks.  finite.py
akantu    Akantu's explicit lumped-mass plane-strain step in its own venv         peers.py
          (benchmarks/akantu_peer.py).
whole     whole runs against their steps (punch Sim3, bars; default outputs),    whole_run.py
          the set-up by phase, the contact share at Sim3, history and field cost;
          the nonlinear scenes (plastic bar, bit-rock with a Drucker-Prager    whole_nonlinear.py
          rock, Taylor bar) run whole from their scene files, the whole by part.
shpb      the SHPB scene's whole run (whole time, ns per element-cycle) and its    shpb.py
          internal forces split between the linear bars and the J2 specimen.

The j2 and finite parts print each step's time over its floor ("x the floor", roofline.py:
the larger of its bytes over the one-core STREAM triad and its arithmetic over the core's
rate, both measured in the run) and its time per element per cycle.

The rest: run.py (options, the order of the parts, the JSON), common.py (modes,
the timer, the run context, child processes), bar.py (the benchmark's bar and
what a step on it costs), machine.py (the machine), tables.py (printing).

Every timing is the median over repeats of a block of calls (a repeat lasts
about ``target`` seconds); under MPI the slowest rank's time counts. Times in the
JSON are in seconds per step (or per call), ``*_ns_per_dof`` in ns per dof per step.
"""
from .run import main

__all__ = ["main"]
