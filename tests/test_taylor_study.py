"""The Taylor bar convergence study (long: `make study-taylor`, deselected from `make test`).

Meshes n_r x 10 n_r for n_r = 4, 8, 12 (square cells, h = R / n_r). The goal
against the converged Q1/P0 results (final length 21.42-21.48 mm, impact-face
radius 7.22-7.23 mm): within 0.5 % (length) and 1 % (radius) at the finest mesh,
and the ledger closing at every mesh.
"""
import pytest

from conftest import load_demo


@pytest.mark.study
def test_taylor_bar_convergence(comm):
    demo = load_demo("taylor_bar")
    rows = []
    for n_r in (4, 8, 12):
        s = demo.run(n_r, comm=comm)
        rows.append((n_r, s["final_length"] * 1e3, s["final_face_radius"] * 1e3, s["eps_p_max"]))
        total = s["kinetic"] + s["stored_elastic"] + s["plastic_work"] + s["activation_loss"]
        assert total == pytest.approx(s["initial_kinetic"], rel=2e-3)
        assert abs(s["kinetic_identity_error"]) < 1e-12
    if comm.rank == 0:
        for r in rows:
            print("n_r = %d: length %.4f mm, face radius %.4f mm, max eps_p %.3f" % r)
    _, length, radius, _ = rows[-1]
    assert length == pytest.approx(21.45, rel=5e-3)
    assert radius == pytest.approx(7.225, rel=1e-2)
