"""What a run tells its user: the impact figures of the summary and where the time went.

:func:`impact_figures` computes, from the history read back from disk, the
energy table and the final state, what an impact researcher reads first (all SI):
per contact the peak force (N) and its time (s), the impulse sum F dt (N s), the
time in contact and the number of separations, and for two bodies that
separate their rebound velocities and the coefficient of restitution
e = (v_upper' - v_lower') / (v_lower - v_upper) (body-mean z velocities before
the first and after the last output). :func:`console_lines` formats the
summary for the console, :func:`energy_line` its energy ledger,
:func:`stable_step_line` each body's stable step at set-up.
"""
from __future__ import annotations

import numpy as np


def contact_figures(time: np.ndarray, force: np.ndarray, n_active: np.ndarray,
                    dt: float) -> dict:
    """Peak force (N) and its time (s), impulse (N s: sum of F over the rows times the row
    spacing, exactly sum F dt with a row every step), time in contact (s), first and last
    contact times (s) and the number of separations (active -> none active)."""
    if time.size == 0:
        return {}
    spacing = np.diff(np.concatenate([[time[0] - dt], time]))
    active = n_active > 0
    k = int(np.argmax(force))
    out = {"peak_force": float(force[k]), "peak_force_time": float(time[k]),
           "impulse": float(np.sum(force * spacing)),
           "time_in_contact": float(np.sum(spacing[active])),
           "n_separations": int(np.sum(active[:-1] & ~active[1:]) + 0),
           "first_contact_time": float(time[active][0]) if active.any() else None,
           "last_contact_time": float(time[active][-1]) if active.any() else None,
           "separated_at_end": bool(not active[-1])}
    return out


def restitution(v_lower: tuple[float, float], v_upper: tuple[float, float]) -> dict:
    """Rebound figures of a body below and one above it (whichever moves): mean z
    velocities (m/s) before (first) and after (second); e = separation / approach speed
    (None when they do not approach)."""
    approach = v_lower[0] - v_upper[0]
    separation = v_upper[1] - v_lower[1]
    return {"velocity_lower_before": v_lower[0], "velocity_upper_before": v_upper[0],
            "velocity_lower_after": v_lower[1], "velocity_upper_after": v_upper[1],
            "restitution": separation / approach if approach > 0 else None}


# a ledger term within this share of the largest is round-off (the ledger's sums run
# over a few dozen rounded terms each): shown as zero
ROUND_OFF = 64 * 2.0 ** -52


def energy_line(s: dict) -> str:
    """The energy ledger of a small-strain summary in one console line: E_n = kinetic +
    strain (+ plastic work of path-dependent bodies), the sum the scheme conserves, and
    E_0 + W_n, W_n the work of loads and contact (activation losses: the part of the
    contact work lost where constraints became active). Terms that are zero, or
    round-off (ROUND_OFF of the largest), are left out."""
    e = s["energy"]
    terms = [e[k] for k in ("kinetic", "strain", "plastic_work", "total", "external_work",
                            "contact_work") if k in e]
    noise = ROUND_OFF * max(abs(x) for x in terms)

    def shown(key: str) -> bool:
        return abs(e.get(key, 0.0)) > noise

    stored = [("kinetic", e["kinetic"]), ("strain", e["strain"])]
    if shown("plastic_work"):
        stored.append(("plastic work", e["plastic_work"]))
    work = [(name, e[key]) for name, key in (("work of loads", "external_work"),
                                            ("contact work", "contact_work")) if shown(key)]
    line = "energy: " + " + ".join(f"{name} {v:.6g} J" for name, v in stored)
    line += f" = {e['total']:.6g} J"
    if work:
        initial = s.get("energy_initial", e["total"] - sum(w for _, w in work))
        line += (f" = initial {initial if abs(initial) > noise else 0.0:.6g} J + "
                 + " + ".join(f"{name} {w:.4g} J" for name, w in work))
        if shown("activation_loss"):
            line += f" (activation losses {e['activation_loss']:.4g} J)"
    return line + f"; balance error {s['energy_balance_error_rel']:.1e} (relative)"


def stable_step_line(stable: dict[str, float], limiting: str, shared: str,
                     basis: str = "element bound") -> str:
    """The set-up's console line of each body's own stable step (s) (``basis``: how it is
    estimated), the body that limits the run marked, then ``shared``: the step every body
    takes (one step for all: no body steps on its own)."""
    each = ", ".join(f"{name} {value:.3g} s" + (" (limits)" if name == limiting else "")
                     for name, value in stable.items())
    return f"stable step per body ({basis}): {each}; {shared}"


def console_lines(s: dict) -> list[str]:
    """The summary's impact figures and timing as console lines."""
    lines = []
    plane = s.get("geometry", {}).get("kind") == "plane_strain"
    axial, v_axial = ("sigma_yy", "v_y") if plane else ("sigma_zz", "v_z")
    if plane:
        lines.append(f"plane strain: masses, forces and energies per thickness t = "
                     f"{s['geometry']['thickness']:.6g} m")
    plastic = any("plastic_work" in b for b in s.get("bodies", {}).values())
    if plastic and "eps_p_max" in s and "final_length" not in s:  # (a bar's shape line has it)
        lines.append(f"plastic strain: largest equivalent plastic strain {s['eps_p_max']:.4g} "
                     "at the end (at a quadrature point)")
    for name, b in s.get("bodies", {}).items():
        lines.append(f"body {name}: mass {b['mass']:.6g} kg, {v_axial} {b['velocity_z_final']:.4g} m/s "
                     f"at the end, kinetic {b['kinetic_energy']:.4g} J, strain "
                     f"{b['strain_energy']:.4g} J"
                     + (f", plastic work {b['plastic_work']:.4g} J" if "plastic_work" in b else ""))
    for name, r in s.get("rigid_bodies", {}).items():
        what = ("prescribed" if r.get("prescribed") else f"mass {r['mass']:.6g} kg")
        lines.append(f"rigid {name}: {what}, {v_axial} {r['v']:.4g} m/s, "
                     f"{'u_y' if plane else 'u_z'} {r['u']:.4g} m"
                     + (f", v_x {r['v_x']:.4g} m/s, u_x {r['u_x']:.4g} m" if "v_x" in r else "")
                     + (f", reaction {r['reaction']:.4g} N" if "reaction" in r else "")
                     + " at the end")
    for c in s.get("impact", []):
        if "peak_force" not in c:
            continue
        line = (f"{'tie' if c.get('tie') else 'contact'} {c['surfaces']}: peak force "
                f"{c['peak_force']:.4g} N at {c['peak_force_time'] * 1e6:.2f} us, impulse "
                f"{c['impulse']:.4g} N s")
        if not c.get("tie"):  # a tie holds from the first step to the last
            line += (f", in contact {c['time_in_contact'] * 1e6:.1f} us, "
                     f"{c['n_separations']} separation(s)")
        if c.get("restitution") is not None and c["separated_at_end"]:
            line += (f"; rebound {c['velocity_lower_after']:.4g} / {c['velocity_upper_after']:.4g}"
                     f" m/s, restitution {c['restitution']:.3f}")
        lines.append(line)
    for f in s.get("friction", []):
        line = (f"friction {'/'.join(f['surfaces'])} ({f['friction']}): slip work {f['slip_work']:.4g} J, "
                f"tangential loss {f['tangential_loss']:.4g} J, peak tangential force "
                f"{f['peak_tangential_force']:.4g} N")
        if "release_loss" in f:
            line += f", release loss {f['release_loss']:.4g} J"
        lines.append(line)
    peaks = s.get("peak_stress")
    if peaks:
        lines.append(f"peak stresses (at field outputs): von Mises {peaks['von_mises'] / 1e6:.4g} MPa "
                     f"at {peaks['von_mises_time'] * 1e6:.2f} us, {axial} in "
                     f"[{peaks[axial + '_min'] / 1e6:.4g}, {peaks[axial + '_max'] / 1e6:.4g}] MPa")
    timing = s.get("timing")
    if timing:
        wall = s["wall_time"]
        parts = ", ".join(f"{k} {v['share']:.0%}" for k, v in timing["phases"].items()
                          if v["share"] >= 0.005)
        steps = (("compiled, frames too" if timing.get("compiled_frames")
                  else "compiled between frames") if timing.get("compiled_steps")
                 else "Python") if "compiled_steps" in timing else None
        lines.append(f"time: loop {wall:.3g} s = {timing['loop_over_steps_median']:.2f} x "
                     f"(steps x median step {s['step_time_median'] * 1e6:.1f} us); {parts}, "
                     f"rest {timing['rest_share']:.0%}" + (f"; steps {steps}" if steps else ""))
        if "ns_per_element_cycle" in s:
            per_body = ", ".join(f"{name} {b['ns_per_element_cycle']:.0f}"
                                 for name, b in s.get("bodies", {}).items()
                                 if "ns_per_element_cycle" in b)
            lines.append(f"cost: {s['ns_per_element_cycle']:.0f} ns per element per cycle "
                         "(the loop's wall time / (cells x steps))"
                         + (f"; f_int per body {per_body} ns" if per_body else ""))
        setup = ", ".join(f"{k} {v:.2f} s" for k, v in s.get("setup_time", {}).items())
        lines.append(f"set-up: {setup}")
    return lines
