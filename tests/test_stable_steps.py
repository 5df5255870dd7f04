"""Each body's own stable step in the summary, and the step of every history row.

Every body takes the run's one Δt; the summary gives each body's own stable step
(``stable_dt``) and the body that limits the run (``stable_dt_limiting``).

Oracles:

* Two bodies that differ only in E: small strain, on triangles and on Q1 quadrilaterals.
  The soft body fills z < 1/2 of a rectangle of 8 x 16 cells. The stiff body, 4 E, fills
  z > 1/2 with the same cells moved up by 1/2. The mesh is dyadic, so every coordinate
  and every difference of coordinates is exact. The element matrices of the stiff body
  are then 4 x the soft body's, and M is the same. So ω scales by √4, and the ratio of
  the stable steps is 2, up to the round-off of an element eigenvalue (bound below).
  On quadrilaterals, the Gauss points' Jacobians take products of coordinates with
  irrational weights, so a translated cell is not bit-for-bit the same; the bound grows
  by z_max / h.
* The run's limit (``dt_critical``) is the smallest body's limit, exactly: it is a
  maximum over a partition of the cells, so it is the same number.
* Finite strain: at the start, the limit the step follows is h / (√2 c) for square cells
  of side h (L = A / diagonal). Here c = √((λ + 2μ)/ρ), computed by hand from E, ν and ρ.
* history.csv's ``dt``. At small strain it equals the summary's dt in every row, with
  the compiled blocks and with the Python steps (17 digits read back exactly). At
  finite strain (a row every step), row 1 is t_1 = Δt = 0.5 x the start's limit exactly.
  From then on, each row's time minus the previous row's equals its ``dt`` to within
  half an ulp of its time: t_n = fl(t_{n-1} + Δt) rounds once, and the subtraction
  t_n - t_{n-1} is exact (Sterbenz: t_n <= 2 t_{n-1} from row 2 on). The limit the step
  follows falls below the start's as the cells flatten.
"""
import math
import os

import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics import scenes
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.materials import LinearElastic
from impact_fenics.materials.finite_j2 import FiniteJ2
from impact_fenics.simulation import Settings, Simulation
from roundoff import rounding
from two_halves import EIG, two_halves

COMM = MPI.COMM_WORLD
E, NU, RHO = 200e9, 0.3, 7850.0
WIDTH, HEIGHT, N_R, N_Z = 0.5, 1.0, 8, 16  # m, cells: h = 1/16 m, dyadic
def _two_bodies(quadrilateral: bool, e_upper: float) -> DeformableModel:
    """The rectangle of 8 x 16 cells: 'soft' (E) below z = 1/2, 'stiff' (e_upper) above."""
    tm = two_halves(COMM, (0.0, 0.0), (WIDTH, HEIGHT), N_R, N_Z, quadrilateral, ("soft", "stiff"))
    model = DeformableModel(tm, [Body("soft", LinearElastic(E=E, nu=NU, density=RHO)),
                                 Body("stiff", LinearElastic(E=e_upper, nu=NU, density=RHO))])
    return model


def _simulation(model, **kw) -> Simulation:
    base = dict(cfl=0.9, n_steps=40, output_every=10, quiet=True, plots=False)
    base.update(kw)
    return Simulation(model, Settings(**base), initial_velocity={"soft": (0.0, 1.0)})


@pytest.mark.parametrize("quadrilateral", [False, True], ids=["triangles", "quadrilaterals"])
@pytest.mark.parametrize("factor", [4.0, 2.25], ids=["E_x4", "E_x2.25"])
def test_stable_step_of_each_body_scales_as_one_over_sqrt_E(quadrilateral, factor):
    """dt_soft / dt_stiff = sqrt(factor), to an element eigenvalue's round-off. dt_critical
    is the stiff body's step, bit for bit, and so is the min over the bodies."""
    sim = _simulation(_two_bodies(quadrilateral, factor * E))
    s = sim.run()
    stable = s["stable_dt"]
    assert set(stable) == {"soft", "stiff"} and s["stable_dt_limiting"] == "stiff"
    assert s["dt_critical"] == min(stable.values()) == stable["stiff"]
    assert s["dt"] == 0.9 * s["dt_critical"]
    # each w^2 within (EIG + the quadrilateral's Jacobians) EPS, two of them, sqrt halves
    jacobian = 3 * 8 * N_Z if quadrilateral else 0  # z_max / h = N_Z
    bound = rounding(EIG + jacobian + 4)  # + the sqrt, 2 / w, the ratio and sqrt(factor)
    ratio = stable["soft"] / stable["stiff"]
    assert abs(ratio / math.sqrt(factor) - 1.0) <= bound, (ratio, bound)


def test_history_dt_is_the_summary_dt_with_blocks_and_python_steps(tmp_path):
    """The dt column holds the run's dt in every row, with the compiled blocks and with the
    Python steps. The time column is n dt."""
    root = COMM.bcast(str(tmp_path), root=0)
    for compiled in (True, False):
        out = os.path.join(root, f"run_{compiled}")
        sim = _simulation(_two_bodies(False, 4.0 * E), out=out, compiled_steps=compiled,
                          history_every=3)
        s = sim.run()
        assert compiled or not sim.compiled_steps  # (blocks where the stack allows them)
        with open(os.path.join(out, "history.csv")) as f:
            head = f.readline().strip().split(",")
        h = np.loadtxt(os.path.join(out, "history.csv"), delimiter=",", skiprows=1, ndmin=2)
        assert head[:3] == ["step", "time", "dt"]
        step = h[:, head.index("step")]
        # every third step and the energy rows' steps (every output_every), the last one
        expected = sorted({*range(1, s["n_steps"] + 1, 3), *range(1, s["n_steps"] + 1, 10),
                           s["n_steps"]})
        assert step.tolist() == expected
        assert np.all(h[:, head.index("dt")] == s["dt"])
        assert np.array_equal(h[:, head.index("time")], step * s["dt"])


def test_console_names_each_body_and_the_limiting_one(capsys):
    sim = _simulation(_two_bodies(False, 4.0 * E), quiet=False)
    sim.run()
    out = capsys.readouterr().out
    if COMM.rank == 0:
        line = [x for x in out.splitlines() if x.startswith("stable step per body")]
        assert len(line) == 1, out
        d = sim.stable_dt
        assert (f"soft {d['soft']:.3g} s, stiff {d['stiff']:.3g} s (limits); every body steps "
                f"dt = {sim.settings.dt:.3g} s") in line[0]
    else:
        assert "stable step" not in out


# the Taylor bar of copper on a dyadic mesh: R = 2^-8 m, 2 x 20 square cells of 2^-9 m
R_BAR, N_BAR = 2.0 ** -8, 2
COPPER = dict(E=117e9, nu=0.35, density=8930.0)


def test_finite_strain_stable_step_and_history_dt(tmp_path):
    out = COMM.bcast(str(tmp_path / "taylor"), root=0)
    sim = scenes.taylor_bar(Settings(history_every=1, out=out, fields=False, plots=False,
                                     quiet=True),
                            FiniteJ2(yield_stress=400e6, hardening=100e6, **COPPER),
                            radius=R_BAR, length=10 * R_BAR, n_r=N_BAR, method="film",
                            t_end=3e-6, dt_interval=3)
    policy = sim.step_policy
    # at the start: h / (sqrt 2 c), c from E, nu, rho by hand
    E_, nu, rho = COPPER["E"], COPPER["nu"], COPPER["density"]
    c = math.sqrt(E_ * (1.0 - nu) / ((1.0 + nu) * (1.0 - 2.0 * nu) * rho))
    h = R_BAR / N_BAR
    # A and the diagonals are exact on the dyadic mesh; L = A / sqrt(2 h^2) rounds twice,
    # c about 8 times on each side and its sqrt once, L / c once: 2 x 12
    assert policy.start == pytest.approx(h / (math.sqrt(2.0) * c), rel=rounding(24))
    assert sim.stable_dt_limiting == "bar"
    s = sim.run()
    with open(os.path.join(out, "history.csv")) as f:
        head = f.readline().strip().split(",")
    rows = np.loadtxt(os.path.join(out, "history.csv"), delimiter=",", skiprows=1, ndmin=2)
    col = {name: rows[:, k] for k, name in enumerate(head)}
    assert col["step"].tolist() == list(range(1, s["n_steps"] + 1))
    # the first step is the safety factor (0.5) times the start's limit, exactly
    assert col["dt"][0] == col["time"][0] == 0.5 * policy.start  # t_1 = 0 + dt exactly
    # the steps vary as the cells flatten; the last one is clipped to t_end
    assert policy.smallest < policy.start
    assert col["dt"].min() < col["dt"].max()
    assert col["time"][-1] == s["t_end"] == pytest.approx(3e-6, rel=rounding(s["n_steps"]))
    step = np.diff(col["time"])
    half_ulp = 0.5 * np.spacing(col["time"][1:])
    assert np.all(np.abs(step - col["dt"][1:]) <= half_ulp)
    # the run's own rows in memory are the file's
    assert np.array_equal(sim.history.data()["dt"], col["dt"])
