# # A new path-dependent material: J2 with Voce (saturating) hardening, at both kinematics
#
# A path-dependent material writes one thing: its point update, compiled with
# numba, and a small class around it that states its kinematics (``strain``).
# At small strain (``strain = "small"``) the update is in the four-component
# notation (rr, tt, zz, rz; tensor shear) of ``impact_fenics.materials.axisym``:
#
#     update(eps, eps_p, state, params, dt, sigma) -> None
#
# and the class has ``linear = False``, ``density``, ``E``, ``nu``, ``lmbda``,
# ``mu``, ``n_state``, ``params()``, ``update``, ``wave_speed()``. At finite strain
# (``strain = "finite"``) the update gives the Kirchhoff stress of the
# deformation gradient (``impact_fenics.materials.hencky``):
#
#     update(F, state, params, dt, tau, work) -> plastic work increment (J/m^3)
#     energy(F, state, params, work) -> stored elastic energy (J/m^3)
#
# with ``density``, ``n_state``, ``params()``, ``initial_state()``,
# ``wave_speed()`` (docs/materials.md states both interfaces). The solver holds
# the state at the quadrature points of every cell; nothing else changes. A
# scene file names such a class by its import path, ``model =
# "custom_plastic_material:FiniteVoceJ2"`` (demos/custom_plastic_material.toml,
# beside this file). Run it with
#
#     scripts/mpirun.sh -n 2 .venv/bin/python demos/custom_plastic_material.py
#
# Four checks, printed, the same on any number of ranks:
#
# 1. with sigma_inf = sigma_0 (no hardening) the new material is the
#    package's J2 with H = 0: the same run gives the same histories to
#    round-off;
# 2. in a bar held at u_r = 0 (uniaxial strain) under a pressure step above
#    its elastic limit, the elastic precursor carries
#    sigma_HEL = sigma_0 (1 - nu)/(1 - 2 nu) (whatever the hardening), measured
#    within the dispersion bound (h / c_L t)^(2/3) of the explicit scheme, and
#    the energy ledger with plastic dissipation closes to round-off;
# 3. at finite strain, without hardening, the Voce material is the package's
#    finite J2 with H = 0 on a short Taylor bar, to round-off;
# 4. the scene file demos/custom_plastic_material.toml runs the finite Voce
#    material by its import path and gives the summary of the same run built in
#    Python, exactly (the same code and arithmetic).

import argparse
import math
import os
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from mpi4py import MPI
from numba import njit

from impact_fenics import loads, meshing
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.errors import require, user_errors
from impact_fenics.materials import J2, FiniteJ2, IsotropicConstants, hencky
from impact_fenics.simulation import Settings, Simulation


# ## The point update
#
# Voce hardening: sigma_y(e) = sigma_0 + (sigma_inf - sigma_0)(1 - exp(-delta e)),
# e the equivalent plastic strain. The radial return of J2 (Simo & Hughes
# 1998, box 3.1) keeps its shape; only the consistency condition
#
#     g(x) = sigma_eq,tr - 3 mu x - sigma_y(e_n + x) = 0
#
# is no longer linear in the increment x: a few Newton steps solve it (g is
# decreasing and convex in x, so Newton from x = 0 converges monotonically).
#
# (Compiled once per run, about a second: numba's on-disk cache depends on how a
# script is imported, so a demo does not rely on it; a material in the package
# uses ``cache=True``.)
@njit
def voce_return(q, mu, e_n, s0, s_inf, delta) -> float:
    """The increment x of the equivalent plastic strain that brings the trial stress q
    (Pa) back to sigma_y(e_n + x); 0 if q is inside the yield surface."""
    if q - (s0 + (s_inf - s0) * (1.0 - math.exp(-delta * e_n))) <= 0.0:
        return 0.0
    x = 0.0
    for _ in range(50):
        decay = math.exp(-delta * (e_n + x))
        g = q - 3 * mu * x - (s0 + (s_inf - s0) * (1.0 - decay))
        dx = g / (3 * mu + (s_inf - s0) * delta * decay)
        x += dx
        if abs(dx) <= 1e-15 * (e_n + x):
            break
    return x


@njit
def voce_update(eps, eps_p, state, params, dt, sigma):
    lmbda, mu, s0, s_inf, delta = params[0], params[1], params[2], params[3], params[4]
    e0, e1, e2, e3 = eps[0] - eps_p[0], eps[1] - eps_p[1], eps[2] - eps_p[2], eps[3] - eps_p[3]
    lt = lmbda * (e0 + e1 + e2)
    t0, t1, t2, t3 = lt + 2 * mu * e0, lt + 2 * mu * e1, lt + 2 * mu * e2, 2 * mu * e3
    m = (t0 + t1 + t2) / 3.0
    d0, d1, d2 = t0 - m, t1 - m, t2 - m
    q = math.sqrt(1.5 * (d0 * d0 + d1 * d1 + d2 * d2 + 2 * t3 * t3))
    e_n = state[0]
    x = voce_return(q, mu, e_n, s0, s_inf, delta)
    if x == 0.0:
        sigma[0], sigma[1], sigma[2], sigma[3] = t0, t1, t2, t3
        return
    k = 1.5 * x / q  # d eps_p = k dev sigma_tr
    eps_p[0] += k * d0
    eps_p[1] += k * d1
    eps_p[2] += k * d2
    eps_p[3] += k * t3
    state[0] = e_n + x
    c = 2 * mu * k
    sigma[0], sigma[1], sigma[2], sigma[3] = t0 - c * d0, t1 - c * d1, t2 - c * d2, t3 - c * t3


# ## The material around it
# (IsotropicConstants gives mu, lmbda, bulk, wave_speed() and the checks of E, nu
# and density; ``strain`` is the kinematics a scene file reads.)
@dataclass(frozen=True)
class VoceJ2(IsotropicConstants):
    """J2 with Voce hardening. E, sigma_0, sigma_inf in Pa; delta (-); density kg/m^3."""

    E: float
    nu: float
    density: float
    sigma_0: float
    sigma_inf: float
    delta: float
    linear: bool = False
    n_state: int = 1
    strain: ClassVar[str] = "small"

    def __post_init__(self) -> None:
        self.check_elastic()
        require(0 < self.sigma_0 <= self.sigma_inf and self.delta >= 0,
                "need 0 < sigma_0 <= sigma_inf (Pa) and delta >= 0")

    def params(self) -> np.ndarray:
        return np.array([self.lmbda, self.mu, self.sigma_0, self.sigma_inf, self.delta])

    @property
    def update(self):
        return voce_update


# ## At finite strain: the same hardening, the Kirchhoff stress of F
#
# The multiplicative split F = F_e F_p with Hencky elasticity and the
# exponential map makes the return a radial return on the principal log
# strains (impact_fenics.materials.hencky does the kinematics: the trial log
# strains of b_e = F C_p^-1 F', the principal Kirchhoff stresses, the return,
# the new C_p^-1). The consistency condition is the one above, in the
# Kirchhoff stress; the plastic work of the step is the exact integral of
# sigma_y over the increment, int sigma_y de = sigma_inf x - (sigma_inf - sigma_0)
# (exp(-delta e_n) - exp(-delta (e_n + x))) / delta (sigma_0 x for delta = 0).
# State: [eps_bar_p, C_p^-1 (rr, zz, rz, tt)].
@njit
def voce_finite_update(F, state, params, dt, tau, work):
    lmbda, mu, s0, s_inf, delta = params[0], params[1], params[2], params[3], params[4]
    hencky.trial_log_strains(F, state, work)
    q = hencky.principal_kirchhoff(lmbda, mu, work)
    e_n = state[0]
    x = voce_return(q, mu, e_n, s0, s_inf, delta)
    if x == 0.0:
        hencky.kirchhoff(work, tau)
        return 0.0
    hencky.radial_return(mu, x, q, work)
    if delta > 0.0:
        wp = s_inf * x - (s_inf - s0) * (math.exp(-delta * e_n)
                                        - math.exp(-delta * (e_n + x))) / delta
    else:
        wp = s0 * x
    state[0] = e_n + x
    hencky.finish(F, work, state, tau)
    return wp


@dataclass(frozen=True)
class FiniteVoceJ2(VoceJ2):
    """Finite-strain J2 with Voce hardening (Hencky elasticity, exponential map): the
    parameters, their checks and params() of :class:`VoceJ2`; density (reference)."""

    n_state: int = 5
    strain: ClassVar[str] = "finite"

    def initial_state(self) -> np.ndarray:
        return np.array([0.0, 1.0, 1.0, 0.0, 1.0])  # eps_bar_p = 0, C_p^-1 = I

    update = staticmethod(voce_finite_update)
    energy = staticmethod(hencky.stored_energy)


# ## The scene: a bar in uniaxial strain under a pressure step
#
# A steel bar (radius 2h, length 1 m) with u_r = 0 on every node, a pressure
# P = 600 MPa held on z = 0, run for 120 us (the precursor does not reach the
# far end). Probes at r = h record sigma_zz and the equivalent plastic strain.
P = 600e6  # Pa
STEEL = dict(E=200e9, nu=0.3, density=7850.0)


def run(material, h: float = 0.005, t_end: float = 1.2e-4, out: str | None = None,
        comm=MPI.COMM_WORLD) -> Simulation:
    tmesh = meshing.bar(radius=2 * h, length=1.0, h=h, structured=True, comm=comm)
    model = DeformableModel(tmesh, [Body("bar", material)])
    sim = Simulation(model, Settings(cfl=0.5, t_end=t_end, output_every=40, out=out, quiet=True),
                     fixed=[model.body_dofs("bar", 0)],
                     loads=[loads.SurfaceLoad(model, "loaded_end", loads.Constant(P))])
    for k, z in enumerate((0.2, 0.4, 0.6)):
        sim.add_probe(f"sigma_zz_{k}", (h, z), "sigma_zz")
        sim.add_probe(f"eps_p_eq_{k}", (h, z), "eps_p_eq")
    sim.run()
    return sim


# ## Check 1: no hardening is J2 with H = 0
def reduction_check(h: float = 0.01) -> float:
    voce = run(VoceJ2(sigma_0=200e6, sigma_inf=200e6, delta=0.0, **STEEL), h=h, t_end=6e-5)
    j2 = run(J2(yield_stress=200e6, hardening=0.0, **STEEL), h=h, t_end=6e-5)
    a, b = voce.history.data(), j2.history.data()
    return max(float(np.abs(a[c] - b[c]).max() / np.abs(b[c]).max())
               for c in a if c.startswith("sigma"))


# ## Check 2: the elastic precursor and the ledger
#
# Along the bar at the final time, the weighted mean of sigma_zz over the
# quadrature points of the band between the plastic and the elastic fronts
# is the precursor's amplitude. With Voce hardening the plastic wave is not a
# single front but a fan; the precursor ahead of it is still sigma_HEL.
def precursor_check(sim: Simulation, h: float) -> dict:
    mat, comm = sim.model.bodies["bar"].material, sim.comm
    t = sim.integrator.n * sim.integrator.dt
    force = sim.integrator.nonlinear[0]
    g = force.geometry
    zq = np.einsum("qi,ni->nq", g.N, sim.model.node_xy[g.dofs][:, :, 1])
    c_L = mat.wave_speed()
    K = mat.bulk
    c_fast_plastic = math.sqrt((K + 4 / 3 * mat.mu * (mat.sigma_inf - mat.sigma_0) * mat.delta
                                / ((mat.sigma_inf - mat.sigma_0) * mat.delta + 3 * mat.mu))
                               / mat.density)  # the fan's leading edge (largest hardening slope)
    w = (h * h * c_L * t) ** (1 / 3)  # width of a dispersive front
    band = (zq > c_fast_plastic * t + 1.5 * w) & (zq < c_L * t - 1.5 * w)
    num = comm.allreduce(float((g.w * force.qs.sigma[:, :, 2])[band].sum()))
    den = comm.allreduce(float(g.w[band].sum()))
    s_hel = mat.sigma_0 * (1 - mat.nu) / (1 - 2 * mat.nu)
    return {"sigma_hel_exact": s_hel, "sigma_hel_measured": -num / den,
            "error_rel": abs(-num / den / s_hel - 1), "bound": (h / (c_L * t)) ** (2 / 3),
            "energy_balance_error_rel": sim.summary["energy_balance_error_rel"],
            "plastic_dissipation": sim.summary["plastic_dissipation"],
            "external_work": sim.summary["energy"]["external_work"]}


# ## Check 3: at finite strain, no hardening is the package's finite J2 with H = 0
#
# A short Taylor bar (copper, R = 3.2 mm, L = 32.4 mm, 227 m/s onto a rigid
# wall, FILM; 2 x 20 quadrilaterals, 10 us: the face yields, eps_bar_p > 1).
R_BAR, L_BAR, V_BAR = 3.2e-3, 32.4e-3, 227.0  # m, m, m/s
COPPER = dict(E=117e9, nu=0.35, density=8930.0)
FINITE_VOCE = dict(sigma_0=400e6, sigma_inf=600e6, delta=10.0)  # Pa, Pa, -
FINITE_KEYS = ("final_length", "final_face_radius", "eps_p_max", "plastic_work",
               "stored_elastic", "kinetic")


def taylor(material, n_r: int = 2, t_end: float = 10e-6, v0: float = V_BAR,
           comm=MPI.COMM_WORLD) -> dict:
    """The summary of a Taylor bar of ``material`` (scenes.taylor_bar, the wall by FILM),
    with its shape and energies at the end."""
    from impact_fenics.scene_keys import ENERGY_EVERY
    from impact_fenics.scenes import taylor_bar

    settings = Settings(quiet=True, plots=False, fields=False, history_every=5,
                        output_every=100, energy_every=ENERGY_EVERY)
    sim = taylor_bar(settings, material, R_BAR, L_BAR, n_r, v0, "film", t_end=t_end,
                     comm=comm)
    summary = sim.run(extra=sim.scene_figures)
    summary["kinetic"] = summary["energy"]["kinetic"]  # (J, at the last half step)
    return summary


def finite_reduction_check(comm=MPI.COMM_WORLD) -> float:
    """The largest relative difference of the summaries (FINITE_KEYS) of the Voce material
    without hardening and FiniteJ2 with H = 0."""
    voce = taylor(FiniteVoceJ2(sigma_0=400e6, sigma_inf=400e6, delta=0.0, **COPPER), comm=comm)
    j2 = taylor(FiniteJ2(yield_stress=400e6, hardening=0.0, **COPPER), comm=comm)
    return max(abs(voce[k] - j2[k]) / abs(j2[k]) for k in FINITE_KEYS)


# ## Check 4: the scene file names the class by its import path
#
# demos/custom_plastic_material.toml holds the same Taylor bar with
# ``model = "custom_plastic_material:FiniteVoceJ2"``: the module is found beside
# the scene file, the keys sigma_0, sigma_inf and delta (and E, nu, density) go
# to the constructor. Built from the file, it is the same run as from Python.
SCENE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "custom_plastic_material.toml")


def scene_check(out: str | None = None, comm=MPI.COMM_WORLD) -> tuple[dict, dict]:
    """(the scene file's summary, the Python route's summary)."""
    from impact_fenics import scene_file

    sc = scene_file.read_scene(SCENE)
    sim = scene_file.build(sc, {"out": out, "quiet": True}, comm)
    from_file = sim.run(extra=sim.scene_figures)
    from_python = taylor(FiniteVoceJ2(**FINITE_VOCE, **COPPER), comm=comm)
    return from_file, from_python


@user_errors
def main(argv=None):
    parser = argparse.ArgumentParser(description="J2 with Voce hardening: a new plastic material.")
    parser.add_argument("--h", type=float, default=0.005, help="element size (m)")
    parser.add_argument("--out", default="results/custom_plastic_material", help="output directory")
    args = parser.parse_args(argv)
    rel = reduction_check()
    material = VoceJ2(sigma_0=200e6, sigma_inf=400e6, delta=50.0, **STEEL)
    sim = run(material, h=args.h, out=args.out)
    c = precursor_check(sim, args.h)
    rel_finite = finite_reduction_check()
    from_file, from_python = scene_check()
    same = all(from_file[k] == from_python[k] for k in FINITE_KEYS + ("n_steps",))
    if MPI.COMM_WORLD.rank == 0:
        print(f"Voce with sigma_inf = sigma_0 vs J2 (H = 0): largest relative history difference "
              f"{rel:.1e} (round-off)")
        print(f"elastic precursor: {c['sigma_hel_measured'] / 1e6:.1f} MPa vs sigma_HEL = "
              f"{c['sigma_hel_exact'] / 1e6:.1f} MPa (error {100 * c['error_rel']:.2f} %, "
              f"dispersion bound {100 * c['bound']:.2f} %)")
        print(f"plastic dissipation {c['plastic_dissipation']:.4g} J of {c['external_work']:.4g} J "
              f"put in; energy balance error {c['energy_balance_error_rel']:.1e}; results in "
              f"{args.out}/")
        print(f"finite strain: Voce with sigma_inf = sigma_0 vs finite J2 (H = 0) on a Taylor "
              f"bar: largest relative summary difference {rel_finite:.1e} (round-off)")
        print(f"scene file {os.path.basename(SCENE)} (model = \"custom_plastic_material:"
              f"FiniteVoceJ2\"): {from_file['n_steps']} steps, final length "
              f"{from_file['final_length'] * 1e3:.4f} mm, max eps_bar_p "
              f"{from_file['eps_p_max']:.4f}; the same summary as from Python: {same}")


if __name__ == "__main__":
    main()
