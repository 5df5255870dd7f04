# # A new material without touching the solver: a transversely isotropic rod
#
# A material is any object with ``density`` (kg/m^3), ``linear``, ``stress(eps)``
# (the 3x3 Cauchy stress in Pa as a UFL expression of the 3x3 axisymmetric
# strain, in (r, theta, z) order) and ``wave_speed()`` (m/s). Here we add a
# fibre-reinforced rod, transversely isotropic about its axis z, and run the
# pressure-pulse scene with it through the ordinary API:
#
#     scripts/mpirun.sh -n 2 .venv/bin/python demos/custom_material.py
#
# Two checks a user can trust, both printed:
#
# 1. with E_p = E_z, nu_p = nu_zp and G_z = E / (2 (1 + nu)) the material is
#    isotropic: its stiffness matrix K equals LinearElastic's to round-off;
# 2. with nu_zp = 0 an axial strain causes no lateral stress, so a z-only
#    field is an exact solution: the pulse travels at sqrt(E_z / rho) whatever
#    the transverse constants (E_p, nu_p, G_z) are.

import argparse
import math
from dataclasses import dataclass

import numpy as np
import ufl
from mpi4py import MPI

from impact_fenics import loads, meshing
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.errors import require, user_errors
from impact_fenics.materials import LinearElastic
from impact_fenics.operators import assemble_stiffness
from impact_fenics.probes import arrival_time
from impact_fenics.simulation import Settings, Simulation


# ## The material
#
# Engineering constants: E_p and nu_p in the isotropic (r, theta) plane, E_z
# along the axis, nu_zp the lateral contraction under an axial stress
# (eps_r = -nu_zp sigma_z / E_z), G_z the shear modulus of the planes that
# contain z. The compliance is symmetric, so nu_pz = nu_zp E_p / E_z. The
# stiffness follows in closed form; it is linear in the strain, so the solver
# assembles K once (``linear = True``).
@dataclass(frozen=True)
class TransverselyIsotropic:
    """Transversely isotropic about z. Moduli in Pa, density in kg/m^3."""

    E_p: float
    nu_p: float
    E_z: float
    nu_zp: float
    G_z: float
    density: float
    linear: bool = True

    def __post_init__(self) -> None:
        require(self.E_p > 0 and self.E_z > 0 and self.G_z > 0,
                "E_p, E_z and G_z must be > 0 (Pa)")
        require(self.density > 0, f"density = {self.density} kg/m^3: must be > 0")
        require(-1.0 < self.nu_p < 1.0 and self._denominator() > 0,
                "the constants do not give a positive definite stiffness: need -1 < nu_p < 1 "
                "and 1 - nu_p - 2 nu_zp^2 E_p / E_z > 0")

    def _denominator(self) -> float:
        nu_pz = self.nu_zp * self.E_p / self.E_z
        return 1.0 - self.nu_p - 2.0 * nu_pz * self.nu_zp

    def stiffness(self) -> dict[str, float]:
        """C11, C12, C13, C33, C44 in Pa ((r, theta, z) order, C44 the rz shear modulus)."""
        nu_pz = self.nu_zp * self.E_p / self.E_z
        d = self._denominator()
        D = (1.0 + self.nu_p) * d
        return {"C11": self.E_p * (1.0 - nu_pz * self.nu_zp) / D,
                "C12": self.E_p * (self.nu_p + nu_pz * self.nu_zp) / D,
                "C13": self.E_p * self.nu_zp / d,
                "C33": self.E_z * (1.0 - self.nu_p) / d,
                "C44": self.G_z}

    def stress(self, eps: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        """Cauchy stress (Pa) of the 3x3 strain tensor in (r, theta, z) order."""
        c = self.stiffness()
        e_rr, e_tt, e_zz, e_rz = eps[0, 0], eps[1, 1], eps[2, 2], eps[0, 2]
        s_rr = c["C11"] * e_rr + c["C12"] * e_tt + c["C13"] * e_zz
        s_tt = c["C12"] * e_rr + c["C11"] * e_tt + c["C13"] * e_zz
        s_zz = c["C13"] * (e_rr + e_tt) + c["C33"] * e_zz
        s_rz = 2.0 * c["C44"] * e_rz
        return ufl.as_tensor([[s_rr, 0, s_rz], [0, s_tt, 0], [s_rz, 0, s_zz]])

    def wave_speed(self) -> float:
        """Fastest quasi-longitudinal speed (m/s) over directions in the (r, z) plane,
        from the largest eigenvalue of the Christoffel matrix."""
        c = self.stiffness()
        phi = np.linspace(0.0, 0.5 * math.pi, 721)
        s2, c2, sc = np.sin(phi) ** 2, np.cos(phi) ** 2, np.sin(phi) * np.cos(phi)
        g_rr = c["C11"] * s2 + c["C44"] * c2
        g_zz = c["C44"] * s2 + c["C33"] * c2
        g_rz = (c["C13"] + c["C44"]) * sc
        top = 0.5 * (g_rr + g_zz) + np.sqrt(0.25 * (g_rr - g_zz) ** 2 + g_rz ** 2)
        return float(math.sqrt(top.max() / self.density))

    def bar_wave_speed(self) -> float:
        """Speed sqrt(E_z / rho) (m/s) of an axial pulse, exact for nu_zp = 0."""
        return math.sqrt(self.E_z / self.density)


def isotropic(E: float, nu: float, density: float) -> TransverselyIsotropic:
    """The isotropic special case of the new material."""
    return TransverselyIsotropic(E_p=E, nu_p=nu, E_z=E, nu_zp=nu, G_z=E / (2.0 * (1.0 + nu)),
                                 density=density)


# ## Check 1: the isotropic case is LinearElastic
#
# Assemble K (N/m) for both materials on the same mesh; the relative
# Frobenius norm of the difference is round-off.
def isotropic_check(E: float = 200e9, nu: float = 0.3, density: float = 7850.0,
                    comm=MPI.COMM_WORLD) -> float:
    tmesh = meshing.bar(radius=0.05, length=0.2, h=0.02, structured=False, comm=comm)
    mats = (LinearElastic(E=E, nu=nu, density=density), isotropic(E, nu, density))
    K = [assemble_stiffness(DeformableModel(tmesh, [Body("bar", m)])) for m in mats]
    diff = K[0].copy()
    diff.axpy(-1.0, K[1])
    return float(diff.norm() / K[0].norm())


# ## Check 2: a pressure pulse in a rod with nu_zp = 0
#
# The rod (radius 0.05 m, length 1 m) of a carbon-epoxy-like material is
# loaded on z = 0 by a 100 MPa trapezoid pulse (rise 20 us, held to 100 us,
# gone by 120 us). Two probes at r = 0.02 m, z = 0.3 and 0.6 m record
# sigma_zz; the measured speed is the probe distance over the difference of
# the times at which each reaches half the plateau.
COMPOSITE = dict(E_p=10e9, nu_p=0.4, E_z=140e9, G_z=5e9, density=1600.0)
P0 = 100e6  # Pa
STATIONS = (0.3, 0.6)  # m


def run(out: str | None = None, h: float = 0.005, nu_zp: float = 0.0, t_end: float = 1.0e-4,
        quiet: bool = True, comm=MPI.COMM_WORLD) -> tuple[dict, Simulation]:
    """Run the pulse in the transversely isotropic rod; returns the summary and the simulation."""
    material = TransverselyIsotropic(nu_zp=nu_zp, **COMPOSITE)
    tmesh = meshing.bar(radius=0.05, length=1.0, h=h, structured=True, comm=comm)
    model = DeformableModel(tmesh, [Body("bar", material)])
    pulse = loads.Trapezoid(peak=P0, t_rise=2e-5, t_fall=1e-4, t_end=1.2e-4)
    settings = Settings(cfl=0.9, t_end=t_end, out=out, output_every=40, quiet=quiet)
    sim = Simulation(model, settings, loads=[loads.SurfaceLoad(model, "loaded_end", pulse)])
    for k, z in enumerate(STATIONS):
        sim.add_probe(f"sigma_zz_{k}", (0.02, z), "sigma_zz")
    summary = sim.run(extra=wave_checks)
    return summary, sim


def wave_checks(sim: Simulation) -> dict:
    material = sim.model.bodies["bar"].material
    h = sim.history.data()
    z = sim.probes.midpoints[:, 1]
    arrivals = [arrival_time(h["time"], -h[f"sigma_zz_{k}"], 0.5 * P0) for k in range(2)]
    c_measured = (z[1] - z[0]) / (arrivals[1] - arrivals[0])
    c_exact = material.bar_wave_speed()
    return {"wave_speed_exact": c_exact, "wave_speed_measured": c_measured,
            "wave_speed_error_rel": abs(c_measured - c_exact) / c_exact,
            "probe_distance": float(z[1] - z[0]), "h": sim.model.tmesh.info["h"]}


@user_errors
def main(argv=None):
    parser = argparse.ArgumentParser(description="A transversely isotropic rod: a new material.")
    parser.add_argument("--h", type=float, default=0.005, help="element size (m)")
    parser.add_argument("--nu-zp", type=float, default=0.0,
                        help="axial Poisson's ratio (0 for the exact 1D oracle)")
    parser.add_argument("--out", default="results/custom_material", help="output directory")
    parser.add_argument("--quiet", action="store_true", help="no progress line")
    args = parser.parse_args(argv)
    rel = isotropic_check()
    s, _ = run(args.out, h=args.h, nu_zp=args.nu_zp, quiet=args.quiet)
    if MPI.COMM_WORLD.rank == 0:
        print(f"isotropic case: |K - K_LinearElastic| / |K| = {rel:.1e} (round-off)")
        print(f"rod (E_z = {COMPOSITE['E_z'] / 1e9:g} GPa, E_p = {COMPOSITE['E_p'] / 1e9:g} GPa, "
              f"nu_zp = {args.nu_zp:g}): wave speed {s['wave_speed_measured']:.1f} m/s vs "
              f"sqrt(E_z/rho) = {s['wave_speed_exact']:.1f} m/s "
              f"(error {100 * s['wave_speed_error_rel']:.2f} %, one element over the probe "
              f"distance is {100 * s['h'] / s['probe_distance']:.2f} %)")
        print(f"energy balance error {s['energy_balance_error_rel']:.1e}; results in {args.out}/")


if __name__ == "__main__":
    main()
