"""The wedge bit into Drucker-Prager rock in plane strain (scenes/wedge_rock.toml,
demos/wedge_indentation.py) and its generator, meshing.wedge_on_block.

Oracles:

- the generator's geometry against its closed form: the block's area W D to round-off;
  the nodes of the tip's arc at R from its centre (0, R) and those of the flank on the
  line tangent to it at half the wedge's angle, within gmsh's placement tolerance; the
  wedge's top half width (a vertex) the formula's; the wedge's area between that of
  the polygon of its corners and the exact one (the polygon plus the arc's circular
  segment R²/2 (θ - sin θ), θ = π/2 - a): the mesh's chords inscribe the arc;
- the blow's energy ledger (kinetic + strain + plastic work = initial + contact work)
  closes to round-off (roundoff.ledger);
- the wedge's momentum: nothing but the contact acts on it (its internal forces sum
  to zero, the symmetry plane holds u_x only, the rock's base holds the rock), so
  m_w v(t) - m_w v0 = sum F dt of the contact force to round-off at every energy row;
- the rock yields under the blow (plastic work, a crushed zone of positive depth) and
  the outputs the demo promises hold it (history.csv's force and tip, fields.xdmf's
  eps_p_eq and yielded);
- the run on all ranks equals the run on one (each rank's own, on COMM_SELF): the
  contact force and the tip's displacement within 1e-10 of their largest values, the
  plastic zone's depth (a cell centroid's) equal.

The runs are the shipped scene shortened to T_END (about 200 steps): the blow's first
4 us, its contact force rising and the rock under the tip yielding.
"""
import math
import os

import numpy as np
import pytest
from dolfinx.fem import locate_dofs_topological
from mpi4py import MPI

from impact_fenics import meshing
from impact_fenics.compat import geometry_dofs, scalar_space
from impact_fenics.errors import InputError
from conftest import load_demo
from roundoff import ledger, rounding

demo = load_demo("wedge_indentation")

T_END = 4e-6  # s
# gmsh places a node within Geometry.Tolerance (1e-8 of the model's size) by its own
# arithmetic (tests/test_meshing.py)
GMSH_TOLERANCE = 1e-8


def _shared(tmp_path):
    return type(tmp_path)(MPI.COMM_WORLD.bcast(str(tmp_path)))


def test_wedge_on_block_geometry():
    angle, R, H, W, D, h = 60.0, 0.001, 0.008, 0.015, 0.01, 0.0005
    tm = meshing.wedge_on_block(wedge_angle=angle, tip_radius=R, wedge_height=H,
                                block_width=W, block_depth=D, h_wedge=h, h_block=h)
    msh, a = tm.mesh, math.radians(0.5 * angle)
    x = msh.geometry.x[:, :2]
    dofs = geometry_dofs(msh)
    n_local = msh.topology.index_map(2).size_local
    tol = GMSH_TOLERANCE * max(W, D + H)

    def area(name):
        c = tm.cells(name)
        c = c[c < n_local]
        p = x[dofs[c]]
        local = 0.5 * np.abs((p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1])
                             - (p[:, 2, 0] - p[:, 0, 0]) * (p[:, 1, 1] - p[:, 0, 1])).sum()
        return MPI.COMM_WORLD.allreduce(float(local))

    # a sum of a few thousand cell areas, each of a few roundings of terms of size W D
    n_cells = MPI.COMM_WORLD.allreduce(int(np.count_nonzero(tm.cells("block") < n_local)))
    assert abs(area("block") - W * D) <= rounding(8 * n_cells, W * D) + 2 * (W + D) * tol
    half = meshing.wedge_half_width(angle, R, H)
    assert half == pytest.approx(R * math.cos(a) + (H - R * (1 - math.sin(a))) * math.tan(a))
    t = (R * math.cos(a), R * (1 - math.sin(a)))  # the flank's tangent point
    polygon = 0.5 * abs(t[0] * H - half * t[1] + half * H)  # shoelace: (0,0), T, S, (0,H)
    theta = 0.5 * math.pi - a
    exact = polygon + 0.5 * R * R * (theta - math.sin(theta))
    wedge = area("wedge")
    print(f"wedge area {wedge:.10g} m^2 between the polygon's {polygon:.10g} and the exact "
          f"{exact:.10g}")
    assert polygon - tol * H <= wedge <= exact + tol * H
    # the face's nodes: on the arc or on the flank
    V = scalar_space(msh, "Lagrange", 1)
    p = V.tabulate_dof_coordinates()[locate_dofs_topological(V, 1, tm.facets("wedge_face")), :2]
    on_arc = np.abs(np.hypot(p[:, 0], p[:, 1] - R) - R) <= tol
    # the flank: the line through T with the direction (sin a, cos a)
    on_flank = np.abs((p[:, 0] - t[0]) * math.cos(a) - (p[:, 1] - t[1]) * math.sin(a)) <= tol
    assert np.all(on_arc | on_flank)
    assert MPI.COMM_WORLD.allreduce(float(x[:, 0].max()), op=MPI.MAX) == pytest.approx(W)
    wedge_nodes = np.unique(dofs[tm.cells("wedge")].ravel())
    top = MPI.COMM_WORLD.allreduce(float(x[wedge_nodes, 0].max(initial=0.0)), op=MPI.MAX)
    assert abs(top - half) <= tol
    for name in ("wedge_top", "block_contact", "block_top", "block_side", "block_bottom", "axis"):
        assert name in tm.facet_names


def test_wedge_on_block_refuses_a_flat_angle():
    with pytest.raises(InputError, match="wedge_angle = 180.0 deg must be in"):
        meshing.wedge_on_block(wedge_angle=180.0)


def test_the_scene_reader_refuses_a_flat_angle_before_any_estimate(tmp_path):
    """A scene with wedge_angle >= 180 is refused when it is read (one line naming the
    key), before the run's estimate is printed or its directory made."""
    from impact_fenics.scene_file import read_scene

    here = os.path.dirname(os.path.abspath(__file__))
    with open(os.path.join(here, "..", "scenes", "wedge_rock.toml")) as f:
        text = f.read()
    lines = [("wedge_angle = 200.0" if ln.startswith("wedge_angle") else ln)
             for ln in text.splitlines()]
    path = tmp_path / "bad.toml"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match="wedge_angle.*must be below 180"):
        read_scene(str(path))


@pytest.fixture(scope="module")
def blow(tmp_path_factory):
    out = os.path.join(_shared(tmp_path_factory.mktemp("wedge")), "run")
    return demo.run(out=out, t_end=T_END), out


def test_the_ledger_closes(blow):
    (s, sim), _ = blow
    bound = ledger(s["n_steps"], s["n_dofs"])
    print(f"energy balance {s['energy_balance_error_rel']:.3g} (bound {bound:.3g}); plastic "
          f"work {sim.energy.data()['plastic_work'][-1]:.4g} J")
    assert s["energy_balance_error_rel"] <= bound
    assert sim.energy.data()["plastic_work"][-1] > 0.0  # the rock has yielded


def test_the_wedge_loses_the_contact_impulse(blow):
    """p_w(n) - m_w v0 = sum over the history rows of steps 1..n+1 of F dt: a row of step
    k records the contact force of the step that ends at k - 1's velocity update (the
    first row, step 1, the activation at t = 0)."""
    (s, sim), _ = blow
    h, e = sim.history.data(), sim.energy.data()
    p0 = e["momentum_z"][0]  # m_w v0: the rock at rest, nothing has acted yet
    impulse = np.cumsum(h["contact_force"] * h["dt"])
    rows = e["step"].astype(int)
    residual = e["momentum_z_wedge"] - p0 - impulse[rows]
    bound = ledger(s["n_steps"], s["n_dofs"]) * abs(p0)
    print(f"momentum residual {np.abs(residual).max():.3g} kg m/s of m v0 = {abs(p0):.4g} "
          f"(bound {bound:.3g}); impulse {impulse[-1]:.4g} N s")
    assert np.abs(residual).max() <= bound
    assert impulse[-1] > 0.01 * abs(p0)  # the blow is under way


def test_the_rock_yields_and_the_outputs_hold_it(blow):
    (s, sim), out = blow
    assert sim.energy.data()["plastic_work"][0] == 0.0  # nothing has pressed at step 0
    assert s["plastic_zone_depth"] > 0.0
    # the outputs the demo promises: the history's force and tip, the plastic fields
    if MPI.COMM_WORLD.rank == 0:
        with open(os.path.join(out, "history.csv")) as f:
            header = f.readline().strip().split(",")
        assert "contact_force" in header and "tip_u_y" in header
        with open(os.path.join(out, "fields.xdmf")) as f:
            text = f.read()
        assert "eps_p_eq" in text and "yielded" in text


def test_all_ranks_equal_one(blow):
    (s, sim), _ = blow
    one, sim1 = demo.run(t_end=T_END, comm=MPI.COMM_SELF)
    h, h1 = sim.history.data(), sim1.history.data()
    for key in ("contact_force", "tip_u_y"):
        scale = np.abs(h1[key]).max()
        diff = np.abs(h[key] - h1[key]).max()
        print(f"{key}: {MPI.COMM_WORLD.size} ranks against 1: {diff:.3g} of {scale:.4g}")
        assert diff <= 1e-10 * scale
    assert s["plastic_zone_depth"] == one["plastic_zone_depth"]
    print(f"peak force {s['force_peak']:.10g} N, plastic zone depth "
          f"{s['plastic_zone_depth'] * 1e3:.6g} mm")
