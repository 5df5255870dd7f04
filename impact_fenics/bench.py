"""The benchmark harness of issue 5: where the time of a step goes, and how far it is from the floor.

    python -m impact_fenics.bench            # the full run (< 10 min on 2 cores)
    python -m impact_fenics.bench --quick    # about a minute
    python -m impact_fenics.bench --smoke    # seconds (the test suite runs this)
    scripts/mpirun.sh -n 2 .venv/bin/python -m impact_fenics.bench --parts scaling,stream

It prints tables and writes every raw median to ``results/bench.json`` (``--out``).
Parts (``--parts``, comma separated; all by default):

step      ns per dof per step of the same update done three ways, in one run:
          the integrator (predict + advance) and the Simulation loop without
          outputs; a bare MatMult (and MatMultAdd, VecAXPY) on the same matrix;
          a SciPy CSR loop (v += A u; u += dt v) on the same matrix.
contact   contact time per step (detection / solve / update) against the number
          of constraints, for a rigid punch and for node pairs, per method.
solvers   FILM's solve_fast / solve_dense alone on synthetic gaps.
scaling   step and MatMult time per dof from ~20k to ~1M dofs.
stream    a STREAM-like bandwidth (VecCopy, VecAXPY, VecWAXPY, VecDot) in GB/s.
ranks     the scaling and stream parts again on 2 ranks (launched with
          scripts/mpirun.sh), the speed-up of 2 ranks over 1 and the bandwidth ratio.
format    AIJ against BAIJ (block size 2) for MatMult and the whole step.
matfree   a compiled matrix-free CST internal force (benchmarks/matfree_cst.py) against MatMult.
akantu    Akantu's explicit lumped-mass plane-strain step in its own venv (benchmarks/akantu_peer.py).

Every timing is the median over repeats of a block of calls (a repeat lasts
about ``target`` seconds); under MPI the slowest rank's time counts. Times in the
JSON are in seconds per step (or per call), ``*_ns_per_dof`` in ns per dof per step.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import platform
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from mpi4py import MPI

BIG = 10 ** 9  # output_every / history_every that never comes
ROOT = Path(__file__).resolve().parents[1]
PARTS = ("step", "contact", "solvers", "scaling", "stream", "ranks", "format", "matfree", "akantu")
SERIAL_ONLY = ("ranks", "matfree", "akantu")  # launchers and serial prototypes
CONTACT_METHODS = ("penalty", "film_fast", "film_dense", "dme")


@dataclass(frozen=True)
class Mode:
    """Sizes and repeats of one kind of run."""

    name: str
    step_dofs: int            # mesh of the step, format and matfree parts
    sim_steps: int            # steps of the Simulation loop
    repeats: int              # repeats of each timed block
    target: float             # seconds per timed block
    sizes: tuple[int, ...]    # dofs of the scaling part
    rank_sizes: tuple[int, ...]  # dofs of the 1-vs-2 ranks comparison
    contact_ns: tuple[int, ...]  # numbers of constraints
    dense_cap: int            # FILM dense runs up to this many constraints (O(n^3))
    contact_steps: int
    dense_steps: int
    stream_n: int             # entries of the STREAM vectors (global)
    solver_ns: tuple[int, ...]
    akantu_dofs: int
    akantu_steps: int


MODES = {
    "smoke": Mode("smoke", step_dofs=4_000, sim_steps=20, repeats=3, target=0.005,
                  sizes=(4_000,), rank_sizes=(4_000,), contact_ns=(40,), dense_cap=40,
                  contact_steps=8, dense_steps=4, stream_n=1 << 20, solver_ns=(40,),
                  akantu_dofs=4_000, akantu_steps=5),
    "quick": Mode("quick", step_dofs=50_000, sim_steps=200, repeats=5, target=0.04,
                  sizes=(20_000, 100_000, 200_000), rank_sizes=(200_000,),
                  contact_ns=(100, 1000), dense_cap=1000, contact_steps=40, dense_steps=5,
                  stream_n=1 << 23, solver_ns=(100, 1000), akantu_dofs=20_000,
                  akantu_steps=20),
    "full": Mode("full", step_dofs=200_000, sim_steps=400, repeats=7, target=0.15,
                 sizes=(20_000, 50_000, 100_000, 200_000, 500_000, 1_000_000),
                 rank_sizes=(200_000, 500_000, 1_000_000),
                 contact_ns=(100, 300, 1000, 2000, 5000, 10_000), dense_cap=2000,
                 contact_steps=100, dense_steps=5, stream_n=1 << 25,
                 solver_ns=(100, 300, 1000, 2000, 5000, 10_000), akantu_dofs=200_000,
                 akantu_steps=30),
}


# ============================================================================ timing

def timeit(fn, comm: MPI.Comm, repeats: int, target: float, min_inner: int = 1) -> dict:
    """Median seconds per call of ``fn`` over ``repeats`` blocks of calls lasting ~``target`` s.

    One call first (warm-up and calibration); under MPI every block starts at a
    barrier and the slowest rank's time counts."""
    clock = time.perf_counter
    comm.Barrier()
    t = clock()
    fn()
    first = comm.allreduce(clock() - t, op=MPI.MAX)
    inner = max(min_inner, int(target / max(first, 1e-9)))
    samples = []
    for _ in range(repeats):
        comm.Barrier()
        t = clock()
        for _ in range(inner):
            fn()
        samples.append(comm.allreduce((clock() - t) / inner, op=MPI.MAX))
    return {"median": float(np.median(samples)), "min": float(min(samples)),
            "max": float(max(samples)), "calls_per_repeat": inner, "repeats": repeats}


def ns_per_dof(seconds: float, n_dofs: int) -> float:
    return 1e9 * seconds / n_dofs


# ============================================================================ machine

def machine_info(comm: MPI.Comm) -> dict:
    import dolfinx
    import petsc4py
    import scipy
    from petsc4py import PETSc

    cpu = "unknown"
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    mem_gb = None
    try:
        with open("/proc/meminfo") as f:
            mem_gb = int(f.readline().split()[1]) / 2 ** 20
    except (OSError, ValueError, IndexError):
        pass
    blas = None
    for lib in ("/usr/lib/x86_64-linux-gnu/libblas.so.3", "/usr/lib/aarch64-linux-gnu/libblas.so.3"):
        if os.path.exists(lib):
            blas = os.path.realpath(lib)
    try:
        affinity = len(os.sched_getaffinity(0))
    except AttributeError:
        affinity = os.cpu_count()
    return {
        "cpu_model": cpu,
        "cores": os.cpu_count(),
        "cores_usable": affinity,
        "memory_gb": mem_gb,
        "hostname": platform.node(),
        "ranks": comm.size,
        "python": platform.python_version(),
        "dolfinx": dolfinx.__version__,
        "petsc": ".".join(str(v) for v in PETSc.Sys.getVersion()),
        "petsc4py": petsc4py.__version__,
        "petsc_int_bytes": np.dtype(PETSc.IntType).itemsize,
        "mpi": MPI.Get_library_version().splitlines()[0].strip(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "blas": blas,
        "openblas_env": {k: v for k, v in os.environ.items() if k.startswith("OPENBLAS_")},
        "load_average": os.getloadavg(),
    }


# ============================================================================ scenes

def bar_mesh(comm: MPI.Comm, dofs: int):
    """A structured steel bar r in [0, 0.5], z in [0, 1] (m) with about ``dofs`` dofs (h = dofs^-1/2)."""
    from . import meshing

    h = 1.0 / math.sqrt(dofs)
    return meshing.bar(radius=0.5, length=1.0, h=h, structured=True, comm=comm), h


def _steel():
    from .materials import LinearElastic
    from .scenes import STEEL

    return LinearElastic(nu=0.3, **STEEL)


def bar_simulation(tmesh, n_steps: int, matrix_type: str = "aij", timers: bool = True):
    """scenes.elastic_bar on a given mesh: a trapezoid pressure on z = 0, no outputs."""
    from . import loads
    from .bodies import Body, DeformableModel
    from .simulation import Settings, Simulation

    model = DeformableModel(tmesh, [Body("bar", _steel())])
    pulse = loads.Trapezoid(peak=100e6, t_rise=2e-5, t_fall=1e-4, t_end=1.2e-4)
    settings = Settings(cfl=0.9, n_steps=n_steps, output_every=BIG, history_every=BIG,
                        fields=False, out=None, quiet=True, matrix_type=matrix_type, timers=timers)
    return Simulation(model, settings, loads=[loads.SurfaceLoad(model, "loaded_end", pulse)])


def random_state(integ, seed: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """A random bounded state (no denormals to skew the timings): u ~ 1e-6 m, v ~ 1e-3 m/s."""
    rng = np.random.default_rng(seed + 7919 * integ.model.comm.rank)
    n = integ.model.n_owned
    u0, v0 = 1e-6 * rng.standard_normal(n), 1e-3 * rng.standard_normal(n)
    integ.set_initial(u0, v0)
    return integ.displacement(np.empty(n)), integ.velocity(np.empty(n))


def _loads_of(integ):
    """(dofs, dt f / m, history) of the integrator's loads, as Integrator.predict applies them."""
    return [(dofs, coef, ld.history)
            for ld, dofs, coef in zip(integ.loads, integ._load_dofs, integ._load_coef)]


class ScipyLoop:
    """The same update on a SciPy CSR copy of A: v += A u (+ loads), u += dt v (serial)."""

    def __init__(self, integ):
        import scipy.sparse as sp

        if integ.model.comm.size != 1:
            raise RuntimeError("the SciPy loop is serial")
        indptr, indices, values = integ.A.getValuesCSR()
        n = integ.model.n_owned
        self.S = sp.csr_matrix((values, indices, indptr), shape=(n, n))
        self.dt = integ.dt
        self.loads = _loads_of(integ)
        self.u = np.zeros(n)
        self.v = np.zeros(n)
        self.n = 0

    def set_state(self, u, v, n: int = 0) -> None:
        self.u[:], self.v[:], self.n = u, v, n

    def _apply_loads(self) -> None:
        t = self.n * self.dt
        for dofs, coef, history in self.loads:
            value = history(t)
            if value != 0.0:
                self.v[dofs] += coef * value

    def step_plain(self) -> None:
        """v += A @ u; u += dt * v (the obvious SciPy code, with temporaries)."""
        self.v += self.S @ self.u
        self._apply_loads()
        self.u += self.dt * self.v
        self.n += 1

    def step_inplace(self) -> None:
        """The same with no temporaries: SciPy's csr_matvec kernel (y += A x) and BLAS daxpy."""
        from scipy.linalg.blas import daxpy
        from scipy.sparse import _sparsetools

        S = self.S
        _sparsetools.csr_matvec(S.shape[0], S.shape[1], S.indptr, S.indices, S.data,
                                self.u, self.v)
        self._apply_loads()
        daxpy(self.v, self.u, a=self.dt)
        self.n += 1


def scipy_equivalence(comm: MPI.Comm = MPI.COMM_SELF, dofs: int = 4000, steps: int = 10) -> dict:
    """Run ``steps`` steps with the integrator and with both SciPy loops from one random
    state; return the largest relative differences of u and v (max |a - b| / max |a|)."""
    tmesh, _ = bar_mesh(comm, dofs)
    sim = bar_simulation(tmesh, n_steps=steps)
    integ = sim.integrator
    u0, v0 = random_state(integ)
    loop = ScipyLoop(integ)
    applied = 0
    for _ in range(steps):
        applied += any(h(integ.t) != 0.0 for _, _, h in loop.loads)
        integ.predict()
        integ.advance()
    u = integ.displacement(np.empty(u0.size))
    v = integ.velocity(np.empty(v0.size))
    out = {"steps": steps, "n_dofs": int(sim.model.n_global), "load_steps": int(applied)}
    for name, stepper in (("plain", loop.step_plain), ("inplace", loop.step_inplace)):
        loop.set_state(u0, v0)
        for _ in range(steps):
            stepper()
        out[f"{name}_u_rel"] = float(np.abs(loop.u - u).max() / np.abs(u).max())
        out[f"{name}_v_rel"] = float(np.abs(loop.v - v).max() / np.abs(v).max())
    out["u_max"] = float(np.abs(u).max())
    return out


def matrix_bytes(A, n_dofs: int) -> dict:
    """Bytes per dof a step and a MatMult move at least (no write-allocate, perfect reuse of x)."""
    from petsc4py import PETSc

    nnz = float(A.getInfo()["nz_used"])  # global sum
    ib = np.dtype(PETSc.IntType).itemsize
    per_row = nnz / n_dofs
    if A.getType().endswith("baij"):
        bs = A.getBlockSize()
        matrix = (8.0 * nnz + ib * nnz / bs ** 2 + ib / bs) / n_dofs
    else:
        matrix = (8.0 + ib) * per_row + ib
    return {"nnz": nnz, "nnz_per_row": per_row, "matrix_bytes_per_dof": matrix,
            "matmult_bytes_per_dof": matrix + 16.0,          # x read, y written
            "step_bytes_per_dof": matrix + 24.0 + 24.0}      # MatMultAdd x, y, z; VecAXPY x, y, y


def measure_step_variants(integ, comm, mode: Mode, what=("step", "matmult", "multadd", "axpy")) -> dict:
    """Integrator step, MatMult, MatMultAdd and VecAXPY on the integrator's own matrix."""
    A = integ.A
    x = A.createVecRight()
    y = A.createVecLeft()
    x.array[:] = integ.u_vec.array
    rng = np.random.default_rng(3 + comm.rank)
    y.array[:] = 1e-3 * rng.standard_normal(y.array.size)
    dt = integ.dt
    fns = {
        "step": lambda: (integ.predict(), integ.advance()),
        "matmult": lambda: A.mult(x, y),
        "multadd": lambda: A.multAdd(x, y, y),
        "axpy": lambda: y.axpy(dt, x),
    }
    out = {}
    for k in what:
        out[k] = timeit(fns[k], comm, mode.repeats, mode.target)
    x.destroy()
    y.destroy()
    return out


def baij_direct(integ):
    """A = -dt M^-1 K as a BAIJ (block size 2) matrix assembled as such: dolfinx's
    create_matrix(form, "baij"), then the integrator's scaling and zero rows, no Mat.copy."""
    from dolfinx import fem
    import dolfinx.fem.petsc  # noqa: F401
    from petsc4py import PETSc

    from .forms import stiffness_form
    from .operators import compile_form

    model = integ.model
    form = compile_form(stiffness_form(model.V, model.parts))
    A = fem.petsc.create_matrix(form, "baij")
    fem.petsc.assemble_matrix(A, form)
    A.assemble()
    scale = A.createVecRight()
    scale.array[:] = -integ.dt / integ.mass
    A.diagonalScale(L=scale)
    A.zeroRows(model.to_global(integ.fixed).astype(PETSc.IntType), diag=0.0)
    scale.destroy()
    return A


# ============================================================================ parts

class Bench:
    def __init__(self, comm: MPI.Comm, mode: Mode, args):
        self.comm = comm
        self.mode = mode
        self.args = args
        self.rank0 = comm.rank == 0
        self.results: dict = {}
        self._meshes: dict = {}
        self.quiet = args.quiet or args.child

    def log(self, *msg) -> None:
        if self.rank0 and not self.quiet:
            print(*msg, flush=True)

    def mesh(self, dofs: int, keep: bool = True):
        if dofs in self._meshes:
            return self._meshes[dofs]
        m = bar_mesh(self.comm, dofs)
        if keep:
            self._meshes[dofs] = m
        return m

    # ------------------------------------------------------------------ step
    def part_step(self) -> dict:
        comm, mode = self.comm, self.mode
        tmesh, h = self.mesh(mode.step_dofs)
        sim = bar_simulation(tmesh, n_steps=mode.sim_steps)
        integ = sim.integrator
        N = int(sim.model.n_global)
        u0, v0 = random_state(integ)
        res = {"n_dofs": N, "h": h, "dt": integ.dt, "matrix_type": integ.A.getType()}
        res.update(matrix_bytes(integ.A, N))
        res["timings"] = measure_step_variants(integ, comm, mode)
        # the Simulation loop without outputs
        integ.set_initial(u0, v0)
        summary = sim.run()
        res["simulation"] = {
            "n_steps": summary["n_steps"],
            "step_time_median": summary["step_time_median"],
            "f_int_median": summary["time_per_step_median"]["f_int"],
            "wall_per_step": summary["wall_time"] / summary["n_steps"],
        }
        t = {k: v["median"] for k, v in res["timings"].items()}
        t["simulation"] = res["simulation"]["step_time_median"]
        t["simulation_wall"] = res["simulation"]["wall_per_step"]
        if comm.size == 1:
            loop = ScipyLoop(integ)
            loop.set_state(u0, v0)
            for name, fn in (("scipy_plain", loop.step_plain), ("scipy_inplace", loop.step_inplace)):
                res["timings"][name] = timeit(fn, comm, mode.repeats, mode.target)
                t[name] = res["timings"][name]["median"]
            res["equivalence"] = scipy_equivalence(MPI.COMM_SELF, dofs=min(N, 8000), steps=10)
        res["ns_per_dof"] = {k: ns_per_dof(v, N) for k, v in t.items()}
        res["ratio_to_matmult"] = {k: v / t["matmult"] for k, v in t.items()}
        res["ratio_to_multadd_axpy"] = {k: v / (t["multadd"] + t["axpy"]) for k, v in t.items()}
        res["implied_bandwidth_gbs"] = {
            "matmult": res["matmult_bytes_per_dof"] / res["ns_per_dof"]["matmult"],
            "step": res["step_bytes_per_dof"] / res["ns_per_dof"]["step"]}
        rows = []
        labels = {"step": "integrator predict+advance", "simulation": "Simulation loop (median step)",
                  "simulation_wall": "Simulation loop (wall / steps)", "matmult": "MatMult A x",
                  "multadd": "MatMultAdd A x + y", "axpy": "VecAXPY",
                  "scipy_plain": "SciPy v += A@u; u += dt*v", "scipy_inplace": "SciPy csr_matvec + daxpy"}
        for k in labels:
            if k in t:
                rows.append([labels[k], f"{1e3 * t[k]:.3f}", f"{res['ns_per_dof'][k]:.2f}",
                             f"{res['ratio_to_matmult'][k]:.2f}"])
        self.table(f"1. The same update three ways: {N:,} dofs, {comm.size} rank(s), "
                   f"{res['nnz_per_row']:.1f} nnz/row, {res['matrix_type']}",
                   ["what", "ms/step", "ns/dof/step", "/ MatMult"], rows)
        self.log(f"   bytes/dof (lower bound): MatMult {res['matmult_bytes_per_dof']:.0f}, step "
                 f"{res['step_bytes_per_dof']:.0f}; implied bandwidth: MatMult "
                 f"{res['implied_bandwidth_gbs']['matmult']:.1f} GB/s, step "
                 f"{res['implied_bandwidth_gbs']['step']:.1f} GB/s")
        if "equivalence" in res:
            e = res["equivalence"]
            self.log(f"   SciPy == PETSc after {e['steps']} steps: max rel. diff u "
                     f"{e['plain_u_rel']:.1e} (plain), {e['inplace_u_rel']:.1e} (in place)")
        return res

    # ------------------------------------------------------------------ contact
    def _contact_sim(self, kind: str, tmesh, n: int, method: str, steps: int):
        from . import loads
        from .bodies import Body, DeformableModel
        from .contact import DME, FILM, Penalty, RigidBody, pair_surfaces, rigid_face
        from .simulation import Settings, Simulation

        m = {"penalty": lambda: Penalty("scaled"), "film_fast": lambda: FILM("fast"),
             "film_dense": lambda: FILM("dense"), "dme": lambda: DME(0.0)}[method]()
        settings = Settings(cfl=0.9, n_steps=steps, output_every=BIG, history_every=1,
                            fields=False, out=None, quiet=True)
        if kind == "rigid":
            model = DeformableModel(tmesh, [Body("block", _steel())])
            area = math.pi * 1.0 ** 2
            pulse = loads.Trapezoid(peak=200e6, t_rise=1e-5, t_fall=9e-5, t_end=1e-4)
            punch = RigidBody("punch", 0.1, force=lambda t: -area * pulse(t))
            sim = Simulation(model, settings, fixed=[model.facet_dofs("bottom", 1)])
            c = sim.add_contact(rigid_face(model, "surface", 1.0, "punch"), m, rigid=punch)
        else:
            model = DeformableModel(tmesh, [Body("striker", _steel()), Body("target", _steel())])
            push = loads.SurfaceLoad(model, "striker_end", loads.Constant(50e6))
            sim = Simulation(model, settings, fixed=[model.facet_dofs("target_end", 1)],
                             loads=[push])
            c = sim.add_contact(pair_surfaces(model, "striker_contact", "target_contact"), m)
        if c.n != n:
            raise RuntimeError(f"{kind} contact: {c.n} constraints instead of {n}")
        return sim

    def _contact_mesh(self, kind: str, n: int):
        from . import meshing

        h = 1.0 / (n - 1)
        if kind == "rigid":  # n surface nodes with r <= 1 m, coarse below
            return meshing.punch_block(width=1.5, depth=0.5, h_surface=h, grading=1.0, h_max=0.25,
                                       breaks=((1.0, n - 1),), comm=self.comm)
        # node pairs: two thin structured strips of radius 1 m, n nodes per face;
        # the striker is pressed against the clamped target, so every pair stays closed
        return meshing.coaxial_bars(radius=1.0, striker_length=2 * h, target_length=2 * h, h=h,
                                    structured=True, comm=self.comm)

    def part_contact(self) -> dict:
        from .errors import UnstableRunError

        mode = self.mode
        out = {"dense_cap": mode.dense_cap, "rigid": [], "pairs": []}
        for kind in ("rigid", "pairs"):
            rows = []
            for n in mode.contact_ns:
                tmesh = self._contact_mesh(kind, n)
                for method in CONTACT_METHODS:
                    if method == "film_dense" and n > mode.dense_cap:
                        continue
                    steps = mode.dense_steps if method == "film_dense" else mode.contact_steps
                    sim = self._contact_sim(kind, tmesh, n, method, steps)
                    rec = {"n_constraints": n, "method": method, "n_dofs": int(sim.model.n_global),
                           "steps": steps}
                    try:
                        s = sim.run()
                        rec["status"] = s["status"]
                    except UnstableRunError as exc:
                        rec["status"] = f"diverged: {exc}"
                        s = sim.summary
                    med = s.get("time_per_step_median", {})
                    for ph in ("contact_detection", "contact_solve", "contact_update", "f_int"):
                        rec[ph] = med.get(ph, float("nan"))
                    rec["contact"] = s.get("contact_cpu_time_per_step_median", float("nan"))
                    rec["step"] = s.get("step_time_median", float("nan"))
                    hist = sim.history.data()
                    na = np.asarray(hist["n_active"], dtype=float)
                    rec["n_active_median"] = float(np.median(na)) if na.size else 0.0
                    rec["contact_ns_per_constraint"] = 1e9 * rec["contact"] / n
                    out[kind].append(rec)
                    rows.append([n, method, rec["n_dofs"], f"{rec['n_active_median']:.0f}",
                                 f"{1e6 * rec['contact_detection']:.1f}",
                                 f"{1e6 * rec['contact_solve']:.1f}",
                                 f"{1e6 * rec['contact_update']:.1f}",
                                 f"{1e6 * rec['contact']:.1f}",
                                 f"{rec['contact_ns_per_constraint']:.0f}",
                                 f"{1e6 * rec['f_int']:.1f}"])
                    del sim
                del tmesh
            title = ("rigid punch (rigid_face on punch_block)" if kind == "rigid"
                     else "node pairs (pair_surfaces on coaxial_bars)")
            self.table(f"2. Contact per step, {title}; FILM dense only up to {mode.dense_cap} "
                       "constraints (O(n^3)); medians in us",
                       ["n", "method", "dofs", "active", "detect", "solve", "update", "contact",
                        "ns/constr", "f_int"], rows)
        return out

    def part_solvers(self) -> dict:
        from .contact.film import solve_dense, solve_fast

        comm, mode = self.comm, self.mode
        rng = np.random.default_rng(11)
        dt = 1e-8
        out = []
        rows = []
        for n in mode.solver_ns:
            m = rng.uniform(0.5e-4, 1.5e-4, n)
            d = dt ** 2 / m
            gap = -1e-9 * rng.uniform(0.0, 1.0, n)
            gap[rng.uniform(size=n) < 0.1] *= -1.0  # some open constraints
            f = np.empty(n)
            for label, kappa in (("pairs", 0.0), ("rigid", dt ** 2 / 0.1)):
                rec = {"n": n, "case": label}
                rec["fast"] = timeit(lambda: solve_fast(gap, d, kappa, f), comm, mode.repeats,
                                     mode.target / 4)["median"]
                if n <= mode.dense_cap:
                    rec["dense"] = timeit(lambda: solve_dense(gap, d, kappa, f), comm,
                                          max(3, mode.repeats // 2), mode.target / 4)["median"]
                rec["numpy_call_floor"] = timeit(lambda: np.maximum(gap, 0.0, out=f), comm,
                                                 mode.repeats, mode.target / 8)["median"]
                out.append(rec)
                rows.append([n, label, f"{1e6 * rec['fast']:.1f}",
                             f"{1e6 * rec['dense']:.1f}" if "dense" in rec else "-",
                             f"{1e6 * rec['numpy_call_floor']:.2f}"])
        self.table("2b. FILM solvers alone on synthetic gaps (us per call)",
                   ["n", "case", "solve_fast", "solve_dense", "one numpy op"], rows)
        return {"cases": out, "dense_cap": mode.dense_cap}

    # ------------------------------------------------------------------ scaling
    def part_scaling(self, sizes=None) -> list:
        from .integrator import Integrator
        from .stability import critical_dt, element_omega_bound

        comm, mode = self.comm, self.mode
        sizes = tuple(sizes or mode.sizes)
        want_matfree = ("matfree" in self.parts and comm.size == 1
                        and (ROOT / "benchmarks" / "matfree_cst.py").exists())
        out, rows = [], []
        for target in sizes:
            tmesh, h = self.mesh(target, keep=(target == mode.step_dofs))
            from .bodies import Body, DeformableModel

            model = DeformableModel(tmesh, [Body("bar", _steel())])
            dt = 0.9 * critical_dt(element_omega_bound(model, model.axis_dofs(owned=False)))
            integ = Integrator(model, dt, model.axis_dofs())
            random_state(integ)
            N = int(model.n_global)
            rec = {"target_dofs": target, "n_dofs": N, "h": h, "ranks": comm.size}
            rec.update(matrix_bytes(integ.A, N))
            rec["timings"] = measure_step_variants(integ, comm, mode)
            t = {k: v["median"] for k, v in rec["timings"].items()}
            if want_matfree:
                rec["matfree"] = self._matfree(model, integ)
                t["matfree"] = rec["matfree"]["force"]
                t["K_matmult"] = rec["matfree"]["K_matmult"]
            rec["ns_per_dof"] = {k: ns_per_dof(v, N) for k, v in t.items()}
            rec["step_over_matmult"] = t["step"] / t["matmult"]
            out.append(rec)
            rows.append([f"{N:,}", f"{rec['nnz_per_row']:.1f}", f"{rec['ns_per_dof']['step']:.2f}",
                         f"{rec['ns_per_dof']['matmult']:.2f}", f"{rec['ns_per_dof']['multadd']:.2f}",
                         f"{rec['ns_per_dof']['axpy']:.2f}", f"{rec['step_over_matmult']:.2f}",
                         f"{rec['step_bytes_per_dof'] / rec['ns_per_dof']['step']:.1f}"]
                        + ([f"{rec['ns_per_dof']['matfree']:.2f}"] if want_matfree else []))
            integ.A.destroy()
            integ.K.destroy()
            del integ, model
        self.table(f"3. Scaling over dofs on {comm.size} rank(s): ns per dof per step",
                   ["dofs", "nnz/row", "step", "MatMult", "MultAdd", "AXPY", "step/MatMult",
                    "step GB/s"] + (["matfree Ku"] if want_matfree else []), rows)
        return out

    def part_stream(self) -> dict:
        from petsc4py import PETSc

        comm, mode = self.comm, self.mode
        n = mode.stream_n
        x = PETSc.Vec().createMPI(n, comm=comm)
        y, w = x.duplicate(), x.duplicate()
        x.set(1.0), y.set(2.0), w.set(0.0)
        # (call, bytes per entry as STREAM counts them, bytes with the write-allocate of
        # a written vector that is not read)
        ops = {"copy": (lambda: x.copy(y), 16, 24), "axpy": (lambda: y.axpy(1e-9, x), 24, 24),
               "waxpy_triad": (lambda: w.waxpy(1e-9, x, y), 24, 32),
               "dot": (lambda: x.dot(y), 16, 16)}
        res = {"n": n, "ranks": comm.size, "vector_mb": 8 * n / 2 ** 20}
        for k, (fn, b, b_wa) in ops.items():
            t = timeit(fn, comm, mode.repeats, mode.target)["median"]
            res[k] = {"seconds": t, "bytes_per_entry": b, "gbs": b * n / t / 1e9,
                      "bytes_per_entry_write_allocate": b_wa, "gbs_write_allocate": b_wa * n / t / 1e9}
        res["best_gbs"] = max(res[k]["gbs_write_allocate"] for k in ops)
        for v in (x, y, w):
            v.destroy()
        self.table(f"4a. STREAM-like bandwidth on {comm.size} rank(s), vectors of "
                   f"{res['vector_mb']:.0f} MB (PETSc Vec ops; BLAS: see meta)",
                   ["op", "B/entry", "GB/s", "B/entry w/ write-alloc", "GB/s w/ write-alloc"],
                   [[k, res[k]["bytes_per_entry"], f"{res[k]['gbs']:.1f}",
                     res[k]["bytes_per_entry_write_allocate"], f"{res[k]['gbs_write_allocate']:.1f}"]
                    for k in ops])
        return res

    def part_ranks(self) -> dict:
        mode = self.mode
        sizes = mode.rank_sizes
        one = {r["target_dofs"]: r for r in self.results.get("scaling", []) if r["target_dofs"] in sizes}
        missing = [s for s in sizes if s not in one]
        if missing:
            for r in self.part_scaling(missing):
                one[r["target_dofs"]] = r
        stream1 = self.results.get("stream") or self.part_stream()
        child = self.launch(2, ["scaling", "stream"], sizes)
        res = {"sizes": list(sizes), "one_rank": {"scaling": [one[s] for s in sizes], "stream": stream1}}
        if "error" in child:
            res["error"] = child["error"]
            self.log(f"   the 2-rank run failed: {child['error']}")
            return res
        res["two_ranks"] = {"scaling": child["scaling"], "stream": child["stream"],
                            "meta": child.get("meta", {})}
        two = {r["target_dofs"]: r for r in child["scaling"]}
        bw = {k: child["stream"][k]["gbs"] / stream1[k]["gbs"] for k in ("copy", "axpy", "waxpy_triad", "dot")}
        res["bandwidth_ratio"] = bw
        rows, speed = [], []
        for s in sizes:
            a, b = one[s], two[s]
            su = {k: a["timings"][k]["median"] / b["timings"][k]["median"]
                  for k in ("step", "matmult", "multadd", "axpy")}
            speed.append({"target_dofs": s, "n_dofs": a["n_dofs"], "speedup": su,
                          "step_ns_per_dof": {"1": a["ns_per_dof"]["step"], "2": b["ns_per_dof"]["step"]},
                          "matmult_ns_per_dof": {"1": a["ns_per_dof"]["matmult"],
                                                 "2": b["ns_per_dof"]["matmult"]}})
            rows.append([f"{a['n_dofs']:,}", f"{a['ns_per_dof']['step']:.2f}",
                         f"{b['ns_per_dof']['step']:.2f}", f"{su['step']:.2f}",
                         f"{a['ns_per_dof']['matmult']:.2f}", f"{b['ns_per_dof']['matmult']:.2f}",
                         f"{su['matmult']:.2f}", f"{su['axpy']:.2f}"])
        res["speedup"] = speed
        self.table("4b. 1 rank against 2 ranks (ns per dof per step, wall clock; speed-up = t1/t2)",
                   ["dofs", "step 1r", "step 2r", "speed-up", "MatMult 1r", "MatMult 2r",
                    "speed-up", "AXPY sp-up"], rows)
        self.log("   STREAM 2 ranks / 1 rank: " + ", ".join(f"{k} {v:.2f}" for k, v in bw.items())
                 + f"  ({stream1['waxpy_triad']['gbs']:.1f} -> "
                   f"{child['stream']['waxpy_triad']['gbs']:.1f} GB/s triad)")
        return res

    def launch(self, n_ranks: int, parts: list[str], sizes) -> dict:
        """This harness on ``n_ranks`` ranks in a fresh mpirun (MPI variables scrubbed)."""
        env = {k: v for k, v in os.environ.items()
               if not k.startswith(("OMPI_", "PMIX_", "OPAL_", "ORTE_", "HYDRA_", "PMI_"))}
        launcher = ROOT / "scripts" / "mpirun.sh"
        runner = [str(launcher)] if launcher.exists() else ["mpirun", "--oversubscribe"]
        fd, path = tempfile.mkstemp(prefix="bench_child_", suffix=".json")
        os.close(fd)
        cmd = runner + ["-n", str(n_ranks), sys.executable, "-m", "impact_fenics.bench",
                        "--mode", self.mode.name, "--parts", ",".join(parts), "--child",
                        "--sizes", ",".join(str(s) for s in sizes), "--out", path]
        self.log(f"   launching: {' '.join(cmd[-12:])}")
        try:
            p = subprocess.run(cmd, env=env, cwd=str(ROOT), capture_output=True, text=True,
                               timeout=600)
            if p.returncode != 0:
                return {"error": f"exit {p.returncode}: {p.stderr[-2000:]}"}
            with open(path) as f:
                return json.load(f)
        except (subprocess.TimeoutExpired, OSError, ValueError) as exc:
            return {"error": str(exc)}
        finally:
            if os.path.exists(path):
                os.remove(path)

    # ------------------------------------------------------------------ format
    def part_format(self) -> dict:
        comm, mode = self.comm, self.mode
        tmesh, h = self.mesh(mode.step_dofs)
        out = {}
        rows = []
        ref = None
        for variant in ("aij", "baij", "baij_direct"):
            t_build = time.perf_counter()
            sim = bar_simulation(tmesh, n_steps=mode.sim_steps,
                                 matrix_type="baij" if variant == "baij" else "aij")
            integ = sim.integrator
            if variant == "baij_direct":
                # what a fix of operators/integrator would give: BAIJ assembled as such (no
                # MatConvert) and A formed without Mat.copy (a copied BAIJ has a slow MatMult)
                integ.A = baij_direct(integ)
            t_build = comm.allreduce(time.perf_counter() - t_build, op=MPI.MAX)
            N = int(sim.model.n_global)
            u0, v0 = random_state(integ)
            rec = {"matrix_type": integ.A.getType(), "block_size": integ.A.getBlockSize(),
                   "n_dofs": N, "build_seconds": t_build}
            rec.update(matrix_bytes(integ.A, N))
            rec["same_A_as_aij"] = self._compare_A(integ.A, ref)
            ref = ref or integ.A
            rec["timings"] = measure_step_variants(integ, comm, mode, ("step", "matmult"))
            rec["K_matmult"] = self._time_K(integ)
            integ.set_initial(u0, v0)
            s = sim.run()
            rec["simulation_step_median"] = s["step_time_median"]
            t = {"step": rec["timings"]["step"]["median"], "matmult": rec["timings"]["matmult"]["median"],
                 "simulation": s["step_time_median"], "K_matmult": rec["K_matmult"]}
            rec["ns_per_dof"] = {k: ns_per_dof(v, N) for k, v in t.items()}
            out[variant] = rec
            rows.append([variant, rec["matrix_type"], f"{rec['matrix_bytes_per_dof']:.0f}",
                         f"{rec['build_seconds']:.2f}",
                         f"{rec['ns_per_dof']['K_matmult']:.2f}", f"{rec['ns_per_dof']['matmult']:.2f}",
                         f"{rec['ns_per_dof']['step']:.2f}", f"{rec['ns_per_dof']['simulation']:.2f}"])
        self.table(f"5. Matrix format, {N:,} dofs, {comm.size} rank(s): ns per dof per step. K as "
                   "assembled (baij: MatConvert), A = -dt M^-1 K as the integrator builds it (Mat.copy); "
                   "baij_direct: BAIJ assembled directly, A without copy",
                   ["variant", "type", "matrix B/dof", "build s", "K MatMult", "A MatMult", "step",
                    "Simulation"], rows)
        return out

    def _compare_A(self, A, ref) -> float:
        """max |A x - ref x| / max |ref x| for a random x (0 for the reference itself)."""
        if ref is None:
            return 0.0
        x, y, z = A.createVecRight(), A.createVecLeft(), A.createVecLeft()
        x.array[:] = np.random.default_rng(2 + self.comm.rank).standard_normal(x.array.size)
        A.mult(x, y)
        ref.mult(x, z)
        diff = self.comm.allreduce(float(np.abs(y.array - z.array).max(initial=0.0)), op=MPI.MAX)
        scale = self.comm.allreduce(float(np.abs(z.array).max(initial=0.0)), op=MPI.MAX)
        x.destroy(), y.destroy(), z.destroy()
        return diff / scale

    def _time_K(self, integ) -> float:
        K = integ.K
        x, y = K.createVecRight(), K.createVecLeft()
        x.array[:] = integ.u_vec.array
        t = timeit(lambda: K.mult(x, y), self.comm, self.mode.repeats, self.mode.target)["median"]
        x.destroy(), y.destroy()
        return t

    # ------------------------------------------------------------------ matrix-free
    def _matfree(self, model, integ) -> dict:
        sys.path.insert(0, str(ROOT / "benchmarks"))
        try:
            from matfree_cst import MatrixFreeCST
        finally:
            sys.path.pop(0)
        mf = MatrixFreeCST(model)
        self._matfree_bytes = sys.modules["matfree_cst"].matfree_bytes_per_dof
        K = integ.K
        x, y = K.createVecRight(), K.createVecLeft()
        x.array[:] = integ.u_vec.array
        xa = x.array.copy()
        f = np.empty_like(xa)
        K.mult(x, y)
        scale = np.abs(y.array).max()
        err = max(float(np.abs(mf.force(xa, f, batched) - y.array).max() / scale)
                  for batched in (False, True))
        rec = {"rel_diff_to_K_u": err,
               "force": timeit(lambda: mf.force(xa, f, True), self.comm, self.mode.repeats,
                               self.mode.target)["median"],
               "force_plain": timeit(lambda: mf.force(xa, f, False), self.comm, self.mode.repeats,
                                     self.mode.target)["median"],
               "K_matmult": timeit(lambda: K.mult(x, y), self.comm, self.mode.repeats,
                                   self.mode.target)["median"],
               "n_cells": mf.n_cells}
        x.destroy(), y.destroy()
        return rec

    def part_matfree(self) -> dict:
        mode = self.mode
        tmesh, h = self.mesh(mode.step_dofs)
        from .bodies import Body, DeformableModel
        from .integrator import Integrator

        model = DeformableModel(tmesh, [Body("bar", _steel())])
        integ = Integrator(model, 1e-8, model.axis_dofs())
        random_state(integ)
        N = int(model.n_global)
        rec = self._matfree(model, integ)
        rec["n_dofs"] = N
        rec["ns_per_dof"] = {"matfree": ns_per_dof(rec["force"], N),
                             "matfree_plain": ns_per_dof(rec["force_plain"], N),
                             "K_matmult": ns_per_dof(rec["K_matmult"], N)}
        rec["matfree_over_matmult"] = rec["force"] / rec["K_matmult"]
        rec["bytes_per_dof"] = {"matfree": self._matfree_bytes(rec["n_cells"], N),
                                "K_matmult": matrix_bytes(integ.K, N)["matmult_bytes_per_dof"]}
        by_size = [(r["n_dofs"], r["matfree"]) for r in self.results.get("scaling", []) if "matfree" in r]
        rows = []
        for n, r in [(N, rec)] + [(n, r) for n, r in by_size if n != N]:
            rows.append([f"{n:,}", f"{ns_per_dof(r['K_matmult'], n):.2f}",
                         f"{ns_per_dof(r['force_plain'], n):.2f}", f"{ns_per_dof(r['force'], n):.2f}",
                         f"{r['force'] / r['K_matmult']:.2f}", f"{r['rel_diff_to_K_u']:.1e}"])
        self.table("6. Matrix-free axisymmetric CST K u (benchmarks/matfree_cst.py: C via cffi, gcc -O3 "
                   "-march=native, serial) against MatMult of K; "
                   f"~{rec['bytes_per_dof']['matfree']:.0f} B/dof against "
                   f"{rec['bytes_per_dof']['K_matmult']:.0f} B/dof",
                   ["dofs", "MatMult ns/dof", "plain loop", "batched (SIMD)", "batched/MatMult",
                    "rel. diff"], rows)
        return rec

    # ------------------------------------------------------------------ akantu
    def part_akantu(self) -> dict:
        mode = self.mode
        py = self.args.akantu_python
        if not os.path.exists(py):
            if self.args.install_akantu:
                venv = os.path.dirname(os.path.dirname(py))
                self.log(f"   installing akantu into {venv} (pip, a separate venv)")
                try:
                    base = getattr(sys, "_base_executable", None) or "/usr/bin/python3"
                    subprocess.run([base, "-m", "venv", venv], check=True, capture_output=True,
                                   timeout=120)
                    subprocess.run([os.path.join(venv, "bin", "pip"), "install", "-q", "akantu"],
                                   check=True, capture_output=True, timeout=480)
                except (subprocess.SubprocessError, OSError) as exc:
                    return {"skipped": f"akantu did not install: {exc}"}
            else:
                reason = (f"no Akantu interpreter at {py}: create it with "
                          f"'/usr/bin/python3 -m venv /tmp/akantu-venv && /tmp/akantu-venv/bin/pip "
                          "install akantu' or pass --install-akantu")
                self.log("   akantu: skipped, " + reason)
                return {"skipped": reason}
        sys.path.insert(0, str(ROOT / "benchmarks"))
        try:
            import akantu_peer
        finally:
            sys.path.pop(0)
        work = tempfile.mkdtemp(prefix="bench_akantu_")
        h = 1.0 / math.sqrt(mode.akantu_dofs)
        mesh = os.path.join(work, "bar.msh")
        akantu_peer.write_mesh(mesh, radius=0.5, length=1.0, h=h)
        out = os.path.join(work, "akantu.json")
        env = dict(os.environ, OMP_NUM_THREADS="1")
        env = {k: v for k, v in env.items() if not k.startswith(("OMPI_", "PMIX_", "PYTHON"))}
        cmd = [py, str(ROOT / "benchmarks" / "akantu_peer.py"), "--mesh", mesh, "--steps",
               str(mode.akantu_steps), "--repeats", str(max(3, mode.repeats // 2)), "--out", out]
        try:
            p = subprocess.run(cmd, env=env, cwd=work, capture_output=True, text=True, timeout=300)
            if p.returncode != 0:
                raise RuntimeError(f"exit {p.returncode}: {p.stderr[-1500:]}")
            with open(out) as f:
                rec = json.load(f)
        except (subprocess.SubprocessError, OSError, ValueError, RuntimeError) as exc:
            self.log(f"   akantu: the run failed: {exc}")
            return {"skipped": f"akantu run failed: {exc}"}
        # ours on the same size, the same kind of measurement (integrator step)
        tmesh, _ = bar_mesh(self.comm, mode.akantu_dofs)
        sim = bar_simulation(tmesh, n_steps=10)
        random_state(sim.integrator)
        N = int(sim.model.n_global)
        t = timeit(lambda: (sim.integrator.predict(), sim.integrator.advance()), self.comm,
                   mode.repeats, mode.target)["median"]
        rec["ours_step_ns_per_dof"] = ns_per_dof(t, N)
        rec["ours_n_dofs"] = N
        rec["akantu_over_ours"] = rec["ns_per_dof_per_step"] / rec["ours_step_ns_per_dof"]
        self.table("7. Peer: Akantu explicit lumped-mass step (plane strain CST, OMP_NUM_THREADS=1) "
                   "against ours (axisymmetric CST)",
                   ["code", "dofs", "ns/dof/step"],
                   [[f"akantu {rec.get('version', '')}", f"{rec['n_dofs']:,}",
                     f"{rec['ns_per_dof_per_step']:.1f}"],
                    ["impact_fenics", f"{N:,}", f"{rec['ours_step_ns_per_dof']:.2f}"]])
        return rec

    # ------------------------------------------------------------------ printing
    def table(self, title: str, headers: list, rows: list) -> None:
        if not self.rank0 or self.quiet:
            return
        cells = [[str(c) for c in r] for r in rows]
        widths = [max(len(str(h)), *(len(r[i]) for r in cells)) if cells else len(str(h))
                  for i, h in enumerate(headers)]
        print(f"\n{title}")
        print("  " + "  ".join(str(h).rjust(w) for h, w in zip(headers, widths)))
        for r in cells:
            print("  " + "  ".join(c.rjust(w) for c, w in zip(r, widths)))
        sys.stdout.flush()

    # ------------------------------------------------------------------ run
    def run(self, parts: list[str]) -> dict:
        self.parts = parts
        clock = time.perf_counter
        t0 = clock()
        meta = machine_info(self.comm)
        meta.update({"mode": self.mode.name, "parts": parts, "started": time.strftime("%Y-%m-%d %H:%M:%S"),
                     "mode_settings": self.mode.__dict__, "part_seconds": {}})
        self.results["meta"] = meta
        self.log(f"impact_fenics benchmark ({self.mode.name}): {meta['cpu_model']}, "
                 f"{meta['cores']} cores, {self.comm.size} rank(s), {meta['memory_gb']:.0f} GB; "
                 f"dolfinx {meta['dolfinx']}, PETSc {meta['petsc']}, {meta['mpi'].split(',')[0]}, "
                 f"numpy {meta['numpy']}, scipy {meta['scipy']}; load average "
                 f"{' '.join(f'{x:.2f}' for x in meta['load_average'])}")
        if meta["load_average"][0] > 0.5 * (meta["cores"] or 1) / 2:
            self.log(f"   note: the machine is busy (load average {meta['load_average'][0]:.2f} on "
                     f"{meta['cores']} cores): timings will be noisy, ratios less so")
        order = [p for p in PARTS if p in parts]
        for part in order:
            if part in SERIAL_ONLY and self.comm.size > 1:
                self.results[part] = {"skipped": "serial-only part (launcher or serial prototype)"}
                continue
            t = clock()
            fn = getattr(self, f"part_{part}")
            if part == "scaling" and self.args.sizes:
                self.results[part] = fn(self.args.sizes)
            elif part in SERIAL_ONLY:  # one process: a failure here cannot strand other ranks
                try:
                    self.results[part] = fn()
                except Exception as exc:  # e.g. no compiler, benchmarks/ not shipped
                    self.results[part] = {"error": f"{type(exc).__name__}: {exc}"}
                    self.log(f"   {part} failed: {exc}")
            else:
                self.results[part] = fn()
            meta["part_seconds"][part] = clock() - t
            self.log(f"   [{part}: {clock() - t:.1f} s]")
        meta["wall_seconds"] = clock() - t0
        meta["load_average_end"] = os.getloadavg()
        self._meshes.clear()
        return self.results


def summary_lines(res: dict) -> list[str]:
    """A few headline figures."""
    lines = []
    st = res.get("step")
    if st and "ns_per_dof" in st:
        r = st["ratio_to_matmult"]
        lines.append(f"step = {r['step']:.2f} x MatMult, Simulation loop = {r['simulation']:.2f} x"
                     + (f", SciPy in place = {r['scipy_inplace']:.2f} x" if "scipy_inplace" in r else ""))
    sm = res.get("stream")
    if st and "ns_per_dof" in st and sm and res["meta"]["ranks"] == 1:
        floor = st["step_bytes_per_dof"] / sm["best_gbs"]
        lines.append(f"bandwidth floor of the step at {st['n_dofs']:,} dofs: "
                     f"{st['step_bytes_per_dof']:.0f} B/dof / {sm['best_gbs']:.1f} GB/s = "
                     f"{floor:.2f} ns/dof; measured {st['ns_per_dof']['step']:.2f} ns/dof "
                     f"({st['ns_per_dof']['step'] / floor:.1f} x the floor)")
    sc = res.get("scaling")
    if sc and sm and res["meta"]["ranks"] == 1:
        big = sc[-1]
        floor = big["step_bytes_per_dof"] / sm["best_gbs"]
        lines.append(f"at {big['n_dofs']:,} dofs: step {big['ns_per_dof']['step']:.2f} ns/dof, "
                     f"{big['ns_per_dof']['step'] / floor:.1f} x the bandwidth floor {floor:.2f} ns/dof")
    rk = res.get("ranks")
    if rk and "speedup" in rk:
        sp = ", ".join(f"{s['n_dofs']:,}: {s['speedup']['step']:.2f}" for s in rk["speedup"])
        lines.append(f"2-rank speed-up of the step: {sp}; triad bandwidth ratio "
                     f"{rk['bandwidth_ratio']['waxpy_triad']:.2f}")
    return lines


def _json_default(o):
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, (np.floating,)):
        return float(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(type(o))


def main(argv=None) -> dict:
    p = argparse.ArgumentParser(prog="python -m impact_fenics.bench", description=__doc__.split("\n")[0])
    g = p.add_mutually_exclusive_group()
    g.add_argument("--quick", action="store_const", const="quick", dest="mode", help="about a minute")
    g.add_argument("--smoke", action="store_const", const="smoke", dest="mode", help="seconds (tests)")
    g.add_argument("--mode", choices=sorted(MODES), dest="mode")
    p.add_argument("--parts", default=",".join(PARTS), help=f"comma separated, of {', '.join(PARTS)}")
    p.add_argument("--sizes", default=None, help="dofs of the scaling part, comma separated")
    p.add_argument("--out", default="results/bench.json", help="JSON output (default results/bench.json)")
    p.add_argument("--akantu-python", default="/tmp/akantu-venv/bin/python",
                   help="the interpreter of a separate venv with akantu")
    p.add_argument("--install-akantu", action="store_true",
                   help="create that venv with pip install akantu if it is missing")
    p.add_argument("--quiet", action="store_true", help="print nothing")
    p.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    mode = MODES[args.mode or "full"]
    parts = [s.strip() for s in args.parts.split(",") if s.strip()]
    bad = [s for s in parts if s not in PARTS]
    if bad:
        p.error(f"unknown part(s) {', '.join(bad)}; use {', '.join(PARTS)}")
    args.sizes = [int(s) for s in args.sizes.split(",")] if args.sizes else None
    comm = MPI.COMM_WORLD
    import logging

    logging.getLogger().setLevel(logging.WARNING)  # the form compiler logs at INFO
    bench = Bench(comm, mode, args)
    results = bench.run(parts)
    if comm.rank == 0:
        out = Path(args.out)
        out.parent.mkdir(parents=True, exist_ok=True)
        tmp = out.with_suffix(out.suffix + ".partial")
        with open(tmp, "w") as f:
            json.dump(results, f, indent=1, default=_json_default)
        os.replace(tmp, out)
        if not bench.quiet:
            for line in summary_lines(results):
                print(line)
            la = results["meta"]["load_average_end"]
            print(f"\nwrote {out} ({results['meta']['wall_seconds']:.0f} s; load average at the end "
                  f"{la[0]:.2f} {la[1]:.2f} {la[2]:.2f})")
    comm.Barrier()
    return results


if __name__ == "__main__":
    main()
