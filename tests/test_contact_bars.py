"""Node-to-node contact of two equal nu = 0 bars against the 1D impact solution.

Two equal bars of length L meeting at relative speed v0 press with the contact
stress rho c0 v0 / 2 for 2 L / c0, then part with their velocities exchanged (nu = 0
admits exact plane waves: every section moves as one, d'Alembert's solution).
The CST mesh only converges to this, so the checks are on face-integrated or
body-averaged quantities with tolerances tied to the element size h:

* contact stress (total force / pi a^2) over the middle 80 % of the contact:
  within 1 % of rho c0 v0 / 2 (the plateau of a 1D wave is exact; only the
  ringing of the front, a few elements long, reaches into the window);
* contact duration within 3 h / c0 of 2 L / c0 (the release is decided at the
  element scale), and its error shrinks when h halves;
* mean velocities after separation exchanged within 2 % of v0 (checked at the
  finer mesh; the error shrinks with h);
* momentum conserved to the round-off of a ledger; no penetration while in contact
  beyond the round-off of the gap arithmetic (tests/roundoff.py).
"""
import math

import numpy as np
import pytest

from impact_fenics import scenes
from impact_fenics.contact import DME, FILM, pair_surfaces
from impact_fenics.errors import InputError
from impact_fenics.simulation import Settings
from roundoff import ledger, rounding
from test_meshing import owned_cells

RHO, E = 7850.0, 200e9
C0 = math.sqrt(E / RHO)
V0, L, A = 5.0, 0.2, 0.05
T_CONTACT = 2 * L / C0


def impact(method, h):
    sim = scenes.bar_impact(Settings(cfl=0.9, t_end=3 * L / C0, output_every=10, quiet=True),
                            method, h=h, nu=0.0, v0=V0, radius=A, striker_length=L,
                            target_length=L, structured=True, observe=None)
    for name in ("striker", "target"):  # the 1D oracle needs both grids structured
        assert owned_cells(sim.model.tmesh, name) == 2 * round(A / h) * round(L / h), name
    summary = sim.run()
    hist, energy = sim.history.data(), sim.energy.data()
    steps = np.flatnonzero(hist["n_active"] > 0)
    dt = sim.settings.dt
    t0 = steps[0] * dt
    window = (hist["time"] > t0 + 0.1 * T_CONTACT) & (hist["time"] < t0 + 0.9 * T_CONTACT)
    return {
        "stress": float(hist["contact_force"][window].mean()) / (math.pi * A ** 2),
        "duration": (steps[-1] - steps[0] + 1) * dt,
        "v_striker": energy["momentum_z_striker"][-1] / sim.body_mass["striker"],
        "v_target": energy["momentum_z_target"][-1] / sim.body_mass["target"],
        "momentum_error": np.abs(energy["momentum_z"] - energy["momentum_z"][0]).max()
                          / abs(energy["momentum_z"][0]),
        "max_penetration": summary["contact"]["max_penetration"],
        "separated": hist["n_active"][-1] == 0,
        "ledger": ledger(summary["n_steps"], summary["n_dofs"]),
        # the committed gap b + u_up - u_lo (2 roundings) after the correction that closed
        # it (6 more) on displacements up to v0 t_end
        "gap_round": rounding(8, V0 * sim.settings.t_end),
    }


@pytest.fixture(scope="module", params=["film", "dme"])
def runs(request):
    make = {"film": lambda: FILM(), "dme": lambda: DME(restitution=0.0)}[request.param]
    return {h: impact(make(), h) for h in (0.01, 0.005)}


@pytest.mark.parametrize("h", [0.01, 0.005])
def test_contact_stress_is_rho_c0_v0_over_2(runs, h):
    assert abs(runs[h]["stress"] / (RHO * C0 * V0 / 2) - 1) <= 0.01


@pytest.mark.parametrize("h", [0.01, 0.005])
def test_contact_duration_is_2L_over_c0(runs, h):
    assert abs(runs[h]["duration"] - T_CONTACT) <= 3 * h / C0


def test_contact_duration_error_shrinks_with_h(runs):
    assert abs(runs[0.005]["duration"] - T_CONTACT) < abs(runs[0.01]["duration"] - T_CONTACT)


def test_velocities_are_exchanged(runs):
    r = runs[0.005]
    assert r["separated"]
    assert abs(r["v_striker"]) <= 0.02 * V0 and abs(r["v_target"] - V0) <= 0.02 * V0
    coarse = runs[0.01]
    assert abs(r["v_target"] - V0) < abs(coarse["v_target"] - V0)


@pytest.mark.parametrize("h", [0.01, 0.005])
def test_momentum_conserved_and_no_penetration(runs, h):
    assert runs[h]["momentum_error"] <= runs[h]["ledger"]
    assert runs[h]["max_penetration"] <= runs[h]["gap_round"]


def test_mismatched_contact_faces_are_refused(tmp_path):
    """Faces meshed with 4 and 5 intervals cannot pair node to node."""
    from mpi4py import MPI

    from impact_fenics import meshing
    from impact_fenics.bodies import Body, DeformableModel
    from impact_fenics.materials import LinearElastic

    path = str(tmp_path / "mismatch.msh")
    if MPI.COMM_WORLD.rank == 0:
        _write_mismatched_bars(path)
    path = MPI.COMM_WORLD.bcast(path)
    MPI.COMM_WORLD.barrier()
    tmesh = meshing.load_msh(path)
    model = DeformableModel(tmesh, [Body("striker", LinearElastic()), Body("target", LinearElastic())])
    with pytest.raises(InputError, match=r"do not pair node to node.*without a partner: \(r="):
        pair_surfaces(model, "striker_contact", "target_contact")


def _write_mismatched_bars(path: str) -> None:
    from impact_fenics.meshing import _gmsh

    gmsh = _gmsh()
    gmsh.model.add("mismatch")
    geo = gmsh.model.geo
    surfaces, tops = [], []
    for k, (z0, z1, n) in enumerate(((-0.1, 0.0, 4), (0.0, 0.1, 5))):
        p = [geo.addPoint(0, z0, 0, 0.02), geo.addPoint(0.05, z0, 0, 0.02),
             geo.addPoint(0.05, z1, 0, 0.02), geo.addPoint(0, z1, 0, 0.02)]
        c = [geo.addLine(p[i], p[(i + 1) % 4]) for i in range(4)]
        surfaces.append(geo.addPlaneSurface([geo.addCurveLoop(c)]))
        tops.append((c[2] if k == 0 else c[0], n))
    geo.synchronize()
    for curve, n in tops:
        gmsh.model.mesh.setTransfiniteCurve(curve, n + 1)
    for tag, name, dim, ents in ((1, "striker", 2, [surfaces[0]]), (2, "target", 2, [surfaces[1]]),
                                 (3, "striker_contact", 1, [tops[0][0]]),
                                 (4, "target_contact", 1, [tops[1][0]])):
        gmsh.model.addPhysicalGroup(dim, ents, tag)
        gmsh.model.setPhysicalName(dim, tag, name)
    gmsh.model.mesh.generate(2)
    gmsh.write(path)
    gmsh.model.remove()


@pytest.mark.parametrize("e", [0.0, 0.5, 1.0])
@pytest.mark.parametrize("positions", ["mass_weighted", "paper"])
def test_dme_pair_collision_law(e, positions):
    """One activation step of DME case 2 against Newton's law and momentum. Round-off:
    the pair's velocities take about 12 roundings (the mass share, the approach velocity,
    the mean and the restitution) of the largest |v|; the positions 5 of the largest
    |u| + |b|; the reported force those of the velocity times m / dt."""
    from types import SimpleNamespace

    m_lo, m_up = np.array([2.0, 1.0, 3.0]), np.array([1.0, 4.0, 3.0])
    u_lo, u_up = np.array([1e-6, 1e-6, 0.0]), np.array([0.0, 5e-7, 0.0])
    v_lo, v_up = np.array([3.0, 1.0, -1.0]), np.array([-1.0, 0.5, 2.0])
    b = np.array([0.0, 0.0, 1e-3])
    # slots: the three lower nodes, then the three upper ones
    c = SimpleNamespace(n=3, rigid=None, dt=1e-6, h_avg=1e-6, b=b, lo=np.arange(3), up=np.arange(3, 6),
                        mass=np.concatenate([m_lo, m_up]), u=np.concatenate([u_lo, u_up]),
                        v=np.concatenate([v_lo, v_up]), force=np.zeros(3),
                        active=np.zeros(3, dtype=bool))
    c.gap = b + u_up - u_lo  # pairs 0 and 1 penetrate, pair 2 is open
    method = DME(restitution=e, positions=positions)
    method.setup(c)
    method.correct(c)
    assert c.active.tolist() == [True, True, False]
    a = c.active
    new_u_lo, new_u_up, new_v_lo, new_v_up = c.u[:3], c.u[3:], c.v[:3], c.v[3:]
    rel_before = v_up[a] - v_lo[a]
    v_round = rounding(12, np.abs(np.concatenate([v_lo, v_up])).max())
    assert np.allclose(new_v_up[a] - new_v_lo[a], -e * rel_before, rtol=0, atol=v_round)
    p_scale = np.abs(m_lo * v_lo).max() + np.abs(m_up * v_up).max()
    assert np.allclose(m_lo * new_v_lo + m_up * new_v_up, m_lo * v_lo + m_up * v_up, rtol=0,
                       atol=rounding(14, p_scale))
    u_scale = np.abs(np.concatenate([u_lo, u_up])).max() + np.abs(b).max()
    assert np.allclose(new_u_lo[a], new_u_up[a] + b[a], rtol=0,
                       atol=rounding(5, u_scale))  # on the manifold
    w = m_lo / (m_lo + m_up) if positions == "mass_weighted" else np.full(3, 0.5)
    assert np.allclose(new_u_lo[a], (w * u_lo + (1 - w) * (u_up + b))[a], rtol=0,
                       atol=rounding(10, u_scale))
    assert new_u_lo[2] == u_lo[2] and new_v_up[2] == v_up[2]  # the open pair is untouched
    # the reported force is the momentum change of the upper node over dt
    assert np.allclose(c.force[a], m_up[a] * (new_v_up[a] - v_up[a]) / c.dt, rtol=0,
                       atol=v_round * m_up.max() / c.dt)
    assert np.all(c.force[a] > 0) and c.force[2] == 0.0
