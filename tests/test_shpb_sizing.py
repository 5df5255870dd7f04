"""The sizing rule of a split Hopkinson bar for a shaped pulse (docs/shpb.md, "Sizing rule").

The pulse of a striker meeting the bar through a spring (impact_fenics/shpb/sizing.py,
(S-1)) against its closed form while the tail ends before the striker's second
reflection, the flat pulse's 2 L_st / c0 exactly, and the scene check's warning on the
scenes' numbers (no run): it fires on the shaped scenes' former bars (a 0.25 m
transmitter) and not on the shipped ones, sized by the rule.
"""
import math
import os

import pytest

from impact_fenics import scene_file
from impact_fenics.shpb.run_analysis import bar_length_warning
from impact_fenics.shpb.sizing import STEPS_PER_RISE, pulse_duration

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


# the shaped scenes' former bars (0.6 m, the gauge at 0.25 m; 0.25 m; 290 us), shorter
# than the rule
FORMER = (("incident_length = 0.85 ", "incident_length = 0.6 "),
          ("transmitter_length = 0.48 ", "transmitter_length = 0.25 "),
          ("z = 0.425 ", "z = 0.25 "))
FORMER_T_END = "t_end = 2.9e-4 "


def _former(name: str) -> tuple:
    t_end = ("t_end = 4.2000412940979004e-4 " if name == "shpb_finite.toml"
             else "t_end = 4.2e-4 ")
    gauge = (("z = 0.91 ", "z = 0.66 ") if name == "shpb_shaped_ld1.toml"
             else ("z = 0.905 ", "z = 0.655 "))  # 0.05 m beyond the specimen
    return FORMER + ((t_end, FORMER_T_END), gauge)


@pytest.mark.parametrize("name", ["shpb.toml", "shpb_shaped.toml", "shpb_finite.toml",
                                  "shpb_shaped_ld1.toml"])
def test_the_shipped_scenes_are_long_enough(tmp_path, name):
    assert bar_length_warning(_scene(tmp_path, name)) is None


@pytest.mark.parametrize("name", ["shpb_shaped.toml", "shpb_finite.toml",
                                  "shpb_shaped_ld1.toml"])
def test_the_former_short_bars_warn(tmp_path, name):
    """The shaper: p = 2.8e7 N/m on 11 pairs, tau = Z / (2 k) = 20.2 us; the pulse to 1 %
    lasts 167 us (the run's shaper contact lasts 169 us, docs/shpb.md), so the
    transmitter needs d_T + c0 T / 2 = 0.05 + 0.42 m; the former 0.25 m returned the free
    end's reflection to its gauge 79 us after the front."""
    line = bar_length_warning(_scene(tmp_path, name, _former(name)))
    assert line is not None and "\n" not in line
    assert "[mesh] transmitter_length = 0.25 m needs 0.4717 m" in line
    assert "[mesh] incident_length = 0.6 m needs 0.8434 m" in line
    assert "[time] t_end = 0.00029 s needs" in line


def test_one_centimetre_short_names_the_transmitter_alone(tmp_path):
    """The shipped shaped scene (0.48 m: d_T + c0 T / 2 = 0.4717 m) with the transmitter
    0.46 m: the warning names it alone."""
    edits = [("transmitter_length = 0.48 ", "transmitter_length = 0.46 ")]
    line = bar_length_warning(_scene(tmp_path, "shpb_shaped.toml", edits))
    assert line is not None and "transmitter_length = 0.46 m needs 0.4717 m" in line
    assert "incident_length" not in line and "t_end" not in line
