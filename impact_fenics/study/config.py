"""Sizes of the study: FULL reproduces the paper (about 15-20 min on 2 cores), QUICK is a
smoke version on tiny meshes (well under a minute) that exercises every code path.

Lengths in m, times in s, penalties in N/m.
"""
from __future__ import annotations

import copy

import numpy as np

# the paper's punch scene (our reading of its section 3.1: docs/results.md); the block of scenes.punch_indentation
PUNCH_BLOCK = dict(width=6.9, depth=0.45, h_surface=0.01, grading=0.055, h_max=0.25,
                   breaks=((1.0, 106), (3.0, 201), (6.0, 302)))

FULL = {
    "name": "full",
    "punch": {
        "block": PUNCH_BLOCK, "radii": (1.0, 3.0, 6.0), "dt": 3.64e-7, "n_steps": 400,
        "pulse": dict(peak=200e6, t_rise=1e-5, t_fall=9e-5, t_end=1e-4),
        "p_paper": 6e9, "timing_repeats": 3,
    },
    "penalty_sweep": {
        "radii": (1.0, 3.0, 6.0),
        "p_values": tuple(np.round(np.logspace(7, 11, 17), -3)) + (1.2e9, 1.4e9, 8e9),
        "beta_targets": (0.25, 0.5, 0.75, 1.0, 1.2, 1.3, 1.4, 1.5, 2.0, 4.0),
    },
    "bars": {
        "h": 0.02, "dt": 1e-6, "t_end": 5e-4, "radius": 0.1, "striker_length": 0.8,
        "target_length": 0.85, "v0": 5.0, "observe": (0.1, 0.2),
        "reference_h": (0.02, 0.01, 0.005, 0.0025, 0.00125, 0.000625),
        "window_c1t_a": 15.0,
    },
    "accuracy": {"h": (0.02, 0.01, 0.005)},
    "stability": {
        "dt_ratios": (0.3, 0.4, 0.45, 0.5, 0.55, 0.6, 0.7, 0.8, 0.9, 0.95, 0.99, 1.01, 1.05, 1.1),
        "bar_steps": 1000, "punch_steps": 1000, "punch_radius": 1.0, "bar_penalty": 1.19e10,
        "beta_targets": (0.25, 0.5, 0.75, 1.0, 1.2, 1.3, 1.33, 1.36, 1.4, 1.5, 2.0, 3.0),
        "beta_steps": 1200,
        "long_steps": 100_000, "long_output_every": 1000,
    },
    "modelling": {
        "widths": (6.15, 6.45, 6.9, 8.0), "depths": (0.15, 0.3, 0.45, 0.9),
        "reference_block": dict(width=8.0, depth=0.9),
        "mesh": ((0.5, 0.11), (0.5, 0.055), (1.0, 0.22), (1.0, 0.11), (1.0, 0.055),
                 (2.0, 0.0275)),
        "mesh_reference": (2.0, 0.0275),
        "punch_height": 0.2,
        "punch_materials": ((1.0, 1.0), (10.0, 1.0), (10.0, 0.1), (100.0, 0.01)),
        "tolerance": 0.02,
    },
}

# tiny: a 1.5 m x 0.3 m block with 50 surface intervals, bars of 0.3 m on coarse meshes
QUICK_BLOCK = dict(width=1.5, depth=0.3, h_surface=0.02, grading=0.3, h_max=0.25,
                   breaks=((0.5, 25), (1.0, 25)))
QUICK = copy.deepcopy(FULL)
QUICK["name"] = "quick"
QUICK["punch"].update(block=QUICK_BLOCK, radii=(0.5, 1.0), n_steps=300, timing_repeats=1)
QUICK["penalty_sweep"].update(radii=(0.5, 1.0), p_values=(1e8, 1e9, 1e10, 1e11),
                              beta_targets=(0.5, 1.0, 2.0))
QUICK["bars"].update(h=0.05, dt=2.5e-6, t_end=1.6e-4, striker_length=0.3, target_length=0.3,
                     reference_h=(0.05, 0.025, 0.0125), window_c1t_a=8.0)
QUICK["accuracy"].update(h=(0.05, 0.025))
QUICK["stability"].update(dt_ratios=(0.3, 0.6, 0.75, 0.9, 1.1), bar_penalty=3e10, bar_steps=400, punch_steps=300,
                          punch_radius=0.5, beta_targets=(0.5, 1.0, 2.0), beta_steps=400,
                          long_steps=2000, long_output_every=100)
QUICK["modelling"].update(widths=(1.1, 1.5), depths=(0.1, 0.3), reference_block=dict(width=1.5, depth=0.3),
                          mesh=((1.0, 0.3), (2.0, 0.3)), mesh_reference=(2.0, 0.3),
                          punch_materials=((1.0, 1.0), (10.0, 0.1)))
