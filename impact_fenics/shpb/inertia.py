"""The specimen's inertia in the Hopkinson test (Davies-Hunter kinematics; docs/shpb.md, "L/D = 1").

A specimen of length L, diameter D, density rho strained at the uniform rate eps_dot
(compression positive) has the axial velocity v(z) = v_back + eps_dot (L - z) (z from the
front face) and the radial velocity nu_p eps_dot r, nu_p the ratio of its radial to its
axial strain rate (nu elastic, 1/2 in plastic flow). Its momentum and the faces' mean
stress then follow from the back face's velocity, eps_dot and eps_ddot alone:

* momentum: m (v_back + L eps_dot / 2), so F_front - F_back = m (a_back + L eps_ddot / 2);
* energy: (F_front + F_back) / (2 A) = sigma + rho (L^2/12 + nu_p^2 D^2/8) eps_ddot,
  sigma the stress that does the specimen's internal work. Both terms raise the faces'
  mean; referred to the back face (Davies and Hunter's form) the same reads
  sigma = F_back / A + rho (L^2/6 - nu_p^2 D^2/8) eps_ddot + rho L a_back / 2.
"""
from __future__ import annotations

import numpy as np


def specimen_momentum(mass: float, length: float, back_force: np.ndarray,
                      impedance: float, rate: np.ndarray) -> np.ndarray:
    """The specimen's axial momentum m (v_back + L eps_dot / 2) (N s) for a uniform strain
    rate ``rate`` (1/s), its back face moving with the transmitter's end, whose velocity
    is the transmitted wave's, v_back = F_back / Z (``back_force`` in N, the bar's
    impedance Z = rho_b c_0 A_b in N s/m); ``mass`` in kg, ``length`` in m."""
    return mass * (np.asarray(back_force) / impedance + 0.5 * length * np.asarray(rate))


def inertia_stress(density: float, length: float, diameter: float, nu_p: float,
                   acceleration: np.ndarray) -> np.ndarray:
    """The faces' mean stress less the specimen's, rho (L^2/12 + nu_p^2 D^2/8) eps_ddot (Pa),
    at the strain acceleration ``acceleration`` (1/s^2); density in kg/m^3, lengths in m:
    the rate of the axial and radial kinetic energies over eps_dot V."""
    return density * (length ** 2 / 12.0 + nu_p ** 2 * diameter ** 2 / 8.0) * np.asarray(
        acceleration)
