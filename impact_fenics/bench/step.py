"""Part 1: the same update three ways on one matrix: the integrator (and the Simulation
loop), bare PETSc MatMult / MatMultAdd / VecAXPY, and a SciPy CSR loop."""
from __future__ import annotations

import numpy as np
from mpi4py import MPI

from .bar import bar_mesh, bar_simulation, matrix_bytes, measure_step_variants, random_state
from .common import per_dof

LABELS = {"step": "integrator predict+advance", "simulation": "Simulation loop (median step)",
          "simulation_wall": "Simulation loop (wall / steps)", "matmult": "MatMult A x",
          "multadd": "MatMultAdd A x + y", "axpy": "VecAXPY",
          "scipy_plain": "SciPy v += A@u; u += dt*v", "scipy_inplace": "SciPy csr_matvec + daxpy"}


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
        # (dofs, dt f / m, history) of each load, as Integrator.predict applies them
        self.loads = [(dofs, coef, ld.history)
                      for ld, dofs, coef in zip(integ.loads, integ._load_dofs, integ._load_coef)]
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


def _simulation_loop(sim) -> dict:
    """The Simulation loop without outputs, from the integrator's present state."""
    summary = sim.run()
    return {"n_steps": summary["n_steps"], "step_time_median": summary["step_time_median"],
            "f_int_median": summary["time_per_step_median"]["f_int"],
            "wall_per_step": summary["wall_time"] / summary["n_steps"],
            "ns_per_element_cycle": summary["ns_per_element_cycle"]}


def part_step(ctx) -> dict:
    comm, mode = ctx.comm, ctx.mode
    tmesh, h = ctx.mesh(mode.step_dofs)
    sim = bar_simulation(tmesh, n_steps=mode.sim_steps)
    integ = sim.integrator
    N = int(sim.model.n_global)
    u0, v0 = random_state(integ)
    res = {"n_dofs": N, "h": h, "dt": integ.dt, "matrix_type": integ.A.getType()}
    res.update(matrix_bytes(integ.A, N))
    res["timings"] = measure_step_variants(ctx, integ)
    integ.set_initial(u0, v0)
    res["simulation"] = _simulation_loop(sim)
    t = {k: v["median"] for k, v in res["timings"].items()}
    t["simulation"] = res["simulation"]["step_time_median"]
    t["simulation_wall"] = res["simulation"]["wall_per_step"]
    if comm.size == 1:
        loop = ScipyLoop(integ)
        loop.set_state(u0, v0)
        for name, fn in (("scipy_plain", loop.step_plain), ("scipy_inplace", loop.step_inplace)):
            res["timings"][name] = ctx.timeit(fn)
            t[name] = res["timings"][name]["median"]
        res["equivalence"] = scipy_equivalence(MPI.COMM_SELF, dofs=min(N, 8000), steps=10)
    res["ns_per_dof"] = per_dof(t, N)
    res["ratio_to_matmult"] = {k: v / t["matmult"] for k, v in t.items()}
    res["ratio_to_multadd_axpy"] = {k: v / (t["multadd"] + t["axpy"]) for k, v in t.items()}
    res["implied_bandwidth_gbs"] = {
        "matmult": res["matmult_bytes_per_dof"] / res["ns_per_dof"]["matmult"],
        "step": res["step_bytes_per_dof"] / res["ns_per_dof"]["step"]}
    rows = [[label, f"{1e3 * t[k]:.3f}", f"{res['ns_per_dof'][k]:.2f}",
             f"{res['ratio_to_matmult'][k]:.2f}"] for k, label in LABELS.items() if k in t]
    ctx.table(f"1. The same update three ways: {N:,} dofs, {comm.size} rank(s), "
              f"{res['nnz_per_row']:.1f} nnz/row, {res['matrix_type']}",
              ["what", "ms/step", "ns/dof/step", "/ MatMult"], rows)
    ctx.log(f"   bytes/dof (lower bound): MatMult {res['matmult_bytes_per_dof']:.0f}, step "
            f"{res['step_bytes_per_dof']:.0f}; implied bandwidth: MatMult "
            f"{res['implied_bandwidth_gbs']['matmult']:.1f} GB/s, step "
            f"{res['implied_bandwidth_gbs']['step']:.1f} GB/s")
    ctx.log(f"   Simulation loop: {res['simulation']['ns_per_element_cycle']:.1f} ns per element "
            "per cycle (the loop's wall time / (cells x steps))")
    if "equivalence" in res:
        e = res["equivalence"]
        ctx.log(f"   SciPy == PETSc after {e['steps']} steps: max rel. diff u "
                f"{e['plain_u_rel']:.1e} (plain), {e['inplace_u_rel']:.1e} (in place)")
    return res
