"""The bars' lengths a split Hopkinson pulse needs (docs/shpb.md, "Sizing rule").

A striker of length L_st (bar speed c0, impedance Z = rho c0 A_b, the bars') meets the
incident bar through a linear spring of stiffness k (N/m; the pulse shaper, or none:
k infinite). With F the spring's force over Z v / 2 (v the striker's speed) the struck
end moves at v F / 2, the striker's face at v (1 - F / 2 - F_in), F_in the tension the
striker's free end sends back (over Z v / 2), and the spring's rate k (v_face - v_end) gives

    tau dF/dt = 1 - F - F_in(t),    F_in(t) = F(t - T0) + F_in(t - T0),
    tau = Z / (2 k),  T0 = 2 L_st / c0,                                       (S-1)

F >= 0 (the spring does not pull: at F = 0 the striker leaves). Before T0 the force
rises as 1 - exp(-t / tau); after it, it decays over a few tau. The pulse lasts T, from
its front until it falls below ``rest`` of its peak for good; k infinite gives T = T0.
The incident gauge (z_I from the struck end, d_I from the specimen) sees the incident
and reflected waves apart, and the reflected wave pass before its own reflection from
the struck end returns, when d_I >= c0 T / 2 and z_I >= c0 T / 2; the transmitter gauge
(d_T from the specimen) sees the transmitted wave pass before the free end's reflection
returns when L_t >= d_T + c0 T / 2; the run records the reflected wave whole when
t_end >= (z_I + 2 d_I) / c0 + T.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

# steps of (S-1) per rise time: the exponential update is exact for a force F_in held over
# the step, and F_in changes by at most 1/STEPS_PER_RISE of the plateau a step, so the
# pulse's end is found to about tau / STEPS_PER_RISE
STEPS_PER_RISE = 2000


def shaper_rise_time(impedance: float, stiffness: float) -> float:
    """tau = Z / (2 k) (s): the rise time of the force through a spring of stiffness k
    (N/m) between a striker and a bar of impedance Z (N s/m) each."""
    return impedance / (2.0 * stiffness)


def pulse_duration(flat: float, rise: float, rest: float) -> float:
    """T (s): the shaped pulse of (S-1), flat duration ``flat`` = T0 = 2 L_st / c0 (s) and
    rise time ``rise`` = tau (s), from its front until it stays below ``rest`` of its peak
    (rise 0: the flat pulse, T = T0)."""
    if rise <= 0.0:
        return flat
    h = rise / STEPS_PER_RISE
    lag = max(1, int(round(flat / h)))
    h = flat / lag  # T0 a whole number of steps: F(t - T0) is a stored sample
    decay = math.exp(-h / rise)
    force, incoming = [0.0], [0.0]  # F and F_in at t = n h
    peak = 0.0
    n = 0
    while True:
        n += 1
        back = n - lag
        f_in = force[back] + incoming[back] if back >= 0 else 0.0
        drive = 1.0 - f_in
        f = max(0.0, drive + (force[-1] - drive) * decay)
        force.append(f)
        incoming.append(f_in)
        peak = max(peak, f)
        if n > lag and f < rest * peak and f <= force[-2]:
            return n * h


@dataclass(frozen=True)
class Needed:
    """What a pulse of duration T (s) needs: the least incident gauge distances from the
    struck end and from the specimen, the least transmitter length beyond its gauge (m)
    and t_end (s)."""

    pulse: float
    gauge_from_struck_end: float
    gauge_from_specimen: float
    transmitter_length: float
    t_end: float


def needed(pulse: float, c0: float, z_i: float, d_i: float) -> Needed:
    """The lengths (m) and end time (s) a pulse of ``pulse`` s needs at the bar speed ``c0``
    (m/s; module docstring), the incident gauge at ``z_i`` m from the struck end and ``d_i``
    m from the specimen (for t_end: the later of the scene's and the needed positions)."""
    half = 0.5 * c0 * pulse
    return Needed(pulse=pulse, gauge_from_struck_end=half, gauge_from_specimen=half,
                  transmitter_length=half,
                  t_end=(max(z_i, half) + 2.0 * max(d_i, half)) / c0 + pulse)
