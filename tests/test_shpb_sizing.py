"""The sizing rule of a split Hopkinson bar for a shaped pulse (docs/shpb.md, "Sizing rule").

The pulse of a striker meeting the bar through a spring (impact_fenics/shpb/sizing.py,
(S-1)) against its closed form while the tail ends before the striker's second
reflection, the flat pulse's 2 L_st / c0 exactly, and the scene check's warning on the
shipped scenes' numbers (no run): it fires on the shaped scenes' 0.25 m transmitter and
not once the bars are as long as it says.
"""
import math
import os

import pytest

from impact_fenics import scene_file
from impact_fenics.shpb.run_analysis import bar_length_warning
from impact_fenics.shpb.sizing import STEPS_PER_RISE, needed, pulse_duration

from scene_texts import ROOT, replace

REST = 0.01  # the pulse's end: 1 % of its peak (waves.REST_FRACTION)


def _closed_form_tail(flat: float, rise: float) -> float:
    """x tau with ((1 - exp(-T0 / tau)) + x) exp(-x) = REST: (S-1) after T0 while the tail
    ends before 2 T0 (F_in = 1 - exp(-(t - T0) / tau) then), by bisection to round-off."""
    lo, hi = 0.0, 60.0
    for _ in range(200):
        x = 0.5 * (lo + hi)
        if ((1.0 - math.exp(-flat / rise)) + x) * math.exp(-x) > REST:
            lo = x
        else:
            hi = x
    return lo * rise


def test_the_flat_pulse_lasts_two_striker_transits():
    assert pulse_duration(79.2e-6, 0.0, REST) == 79.2e-6


@pytest.mark.parametrize("ratio", [10.0, 20.0, 40.0])
def test_the_shaped_pulse_matches_its_closed_form(ratio):
    """T0 / tau = ratio, the tail (about 6.6 tau) ending before 2 T0. The integration holds
    F_in over a step of h = tau / STEPS_PER_RISE (exact in F otherwise) and returns the
    end on the step grid: within 2 h of the closed form."""
    flat, rise = 1.0, 1.0 / ratio
    tail = _closed_form_tail(flat, rise)
    assert tail < flat
    h = rise / STEPS_PER_RISE
    assert abs(pulse_duration(flat, rise, REST) - (flat + tail)) <= 2.0 * h


def _scene(tmp_path, name: str, edits=()) -> scene_file.Scene:
    with open(os.path.join(ROOT, "scenes", name)) as f:
        text = f.read()
    for old, new in edits:
        text = replace(text, old, new)
    path = tmp_path / name
    path.write_text(text)
    return scene_file.read_scene(str(path))


def test_the_flat_scene_is_long_enough(tmp_path):
    assert bar_length_warning(_scene(tmp_path, "shpb.toml")) is None


@pytest.mark.parametrize("name", ["shpb_shaped.toml", "shpb_finite.toml",
                                  "shpb_shaped_ld1.toml"])
def test_the_shaped_scenes_warn_on_the_short_transmitter(tmp_path, name):
    """The shaper: p = 2.8e7 N/m on 11 pairs, tau = Z / (2 k) = 20.2 us; the pulse to 1 %
    lasts 167 us (the run's shaper contact lasts 169 us, docs/shpb.md), so the
    transmitter needs d_T + c0 T / 2 = 0.05 + 0.42 m; the shipped 0.25 m returns the free
    end's reflection to its gauge 79 us after the front."""
    line = bar_length_warning(_scene(tmp_path, name))
    assert line is not None and "\n" not in line
    assert "[mesh] transmitter_length = 0.25 m needs 0.4717 m" in line
    assert "[mesh] incident_length = 0.6 m needs 0.8434 m" in line


def test_long_enough_bars_do_not_warn(tmp_path):
    """The shaped scene on the bars the rule asks for (rounded up to the centimetre): the
    incident bar 0.85 m, its gauge at 0.425 m; the transmitter 0.48 m; t_end from the
    rule."""
    c0 = math.sqrt(200e9 / 7850.0)
    z_i, l_i, l_t = 0.425, 0.85, 0.48
    base = _scene(tmp_path, "shpb_shaped.toml")
    t_end = needed(167.1e-6, c0, z_i, l_i - z_i).t_end + 1e-6
    edits = [("incident_length = 0.6 ", f"incident_length = {l_i} "),
             ("transmitter_length = 0.25 ", f"transmitter_length = {l_t} "),
             ("z = 0.25 ", f"z = {z_i} "),
             ("z = 0.655 ", f"z = {l_i + 0.005 + 0.05} "),
             ("point = [0.0, 0.60025]", f"point = [0.0, {l_i + 0.00025}]"),
             ("point = [0.0, 0.60475]", f"point = [0.0, {l_i + 0.00475}]"),
             ("t_end = 2.9e-4 ", f"t_end = {t_end:.6e} ")]
    assert base.time["t_end"] < t_end
    assert bar_length_warning(_scene(tmp_path, "shpb_shaped.toml", edits)) is None
    # one centimetre short of the rule's transmitter: the warning names it alone
    short = edits[:1] + [("transmitter_length = 0.25 ", "transmitter_length = 0.46 ")] + edits[2:]
    line = bar_length_warning(_scene(tmp_path, "shpb_shaped.toml", short))
    assert line is not None and "transmitter_length = 0.46 m needs 0.4717 m" in line
    assert "incident_length" not in line and "t_end" not in line
