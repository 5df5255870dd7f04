"""J2 in scene files: the keys of [materials.NAME] model = "j2", validated like the rest.

Bad input gives one line "error: [table] key = value: problem" and exit 2 before
anything is written (in process, serially and under mpirun); the plastic scene
of scenes/ runs and books its plastic work in the ledger.
"""
import json
import os

import pytest
from mpi4py import MPI

from impact_fenics import cli
from roundoff import ledger
from scene_texts import PAIR, ROOT, replace

J2_TARGET = replace(PAIR, '[bodies.target]\nmaterial = "steel"',
                    '[bodies.target]\nmaterial = "soft"\n\n[materials.soft]\nmodel = "j2"\n'
                    'E = 200e9\nnu = 0.3\ndensity = 7850.0\nyield_stress = 1e6\nhardening = 1e9')

CASES = [
    ("unknown model", replace(J2_TARGET, 'model = "j2"', 'model = "tresca"'),
     '[materials.soft] model = "tresca": use one of elastic, j2'),
    ("no yield stress", replace(J2_TARGET, "yield_stress = 1e6\n", ""),
     "[materials.soft] yield_stress is missing"),
    ("negative yield stress", replace(J2_TARGET, "yield_stress = 1e6", "yield_stress = -1e6"),
     "[materials.soft] yield_stress = -1000000.0: must be > 0"),
    ("softening", replace(J2_TARGET, "hardening = 1e9", "hardening = -1e9"),
     "[materials.soft] hardening = -1000000000.0: must be >= 0"),
    ("negative viscosity", replace(J2_TARGET, "hardening = 1e9", "viscosity = -1.0"),
     "[materials.soft] viscosity = -1.0: must be >= 0"),
    ("plastic key on an elastic material", replace(PAIR, "density = 7850.0",
                                                   "density = 7850.0\nyield_stress = 1e6"),
     '[materials.steel] yield_stress = 1000000.0: only for model = "j2"'),
    ("plastic probe without a plastic body", replace(PAIR, 'quantity = "sigma_zz"',
                                                     'quantity = "eps_p_eq"'),
     '[probes #1] quantity = "eps_p_eq": needs a body of a plastic material'),
]


@pytest.mark.parametrize("text, expected", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_bad_plastic_input(tmp_path, capsys, text, expected):
    scene = tmp_path / "scene.toml"
    scene.write_text(text)
    with pytest.raises(SystemExit) as exit_:
        cli.main(["run", str(scene), "--quiet", "--out", str(tmp_path / "out")])
    assert exit_.value.code == 2
    lines = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    if MPI.COMM_WORLD.rank == 0:
        assert len(lines) == 1 and lines[0].startswith("error: " + expected), lines
    assert not (tmp_path / "out").exists() and not (tmp_path / "out.partial").exists()


def test_j2_scene_runs_and_books_plastic_work(tmp_path):
    """The tiny pair with a soft J2 target (yield stress 1 MPa) and the scene of scenes/."""
    comm = MPI.COMM_WORLD
    base = comm.bcast(str(tmp_path) if comm.rank == 0 else None, root=0)
    for k, path in enumerate((None, os.path.join(ROOT, "scenes", "plastic_bar_impact.toml"))):
        if path is None:
            path = os.path.join(base, "scene.toml")
            if comm.rank == 0:
                with open(path, "w") as f:
                    f.write(J2_TARGET)
            comm.Barrier()
        out = os.path.join(base, f"out{k}")
        assert cli.main(["run", path, "--out", out, "--quiet"]) == 0
        with open(os.path.join(out, "summary.json")) as f:
            summary = json.load(f)
        assert summary["plastic_dissipation"] > 0
        assert summary["energy_balance_error_rel"] <= ledger(summary["n_steps"],
                                                             summary["n_dofs"])
        # the cell kernel specialised on the material's update compiles at set-up (about
        # a second), never inside the timed loop
        assert summary["timing"]["compiled_in_loop"] == []
