"""The Taylor bar on a rough anvil: Coulomb friction on the finite-strain wall.

The copper Taylor bar (scenes/taylor_bar.toml on an n_r = 4 mesh: 4 x 41 quadrilaterals)
at 227 m/s onto the fixed wall with friction μ = 0, 0.1, 0.2, 0.5 and "stick", FILM and
DME, 80 us. The oracles (docs/friction.md, the rough anvil):

- the foot radius (the largest current r of a boundary node within h = R / n_r of the
  anvil at the end) falls monotonically with μ: friction holds the foot back;
- the ledger K + W_int + L = K_0 closes within the finite ledger's round-off bound
  (roundoff.ledger), the tangential pass's share of the kinetic identity booked with
  the normal one;
- full stick is a held face: until the first step at which a face node's normal
  multiplier would be tensile (the face node leaves the active set), the stick run
  equals, to round-off, a run whose face nodes are held in r and z and whose other
  boundary nodes meet the same wall with "stick".

The same test runs unchanged on 1, 2 and 3 ranks (the gathered wall decides on every
rank alike); the figures are in docs/friction.md and docs/taylor_bar.md.
"""
import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics.contact.plane import boundary_nodes, contact_radius, foot_radius
from impact_fenics.scene_file import build, read_scene
from roundoff import EPS, ledger

COMM = MPI.COMM_WORLD
N_R = 4
MUS = ("0.0", "0.1", "0.2", "0.5", '"stick"')
# the held run: the stick scene with its impact face held in r and z from t = 0
HELD = '\n[[fixed]]\nfacet = "bottom"\ncomponents = ["r", "z"]\n'


def _scene(tmp, method: str, friction: str, t_end: float = 80e-6, held: bool = False):
    text = open("scenes/taylor_bar.toml").read()
    text = text.replace('method = "film"', f'method = "{method}"\nfriction = {friction}')
    text = text.replace("n_r = 8", f"n_r = {N_R}").replace("t_end = 80e-6", f"t_end = {t_end!r}")
    text += HELD if held else ""
    path = tmp / f"{method}_{friction.strip(chr(34))}{'_held' if held else ''}.toml"
    if COMM.rank == 0:
        path.write_text(text)
    COMM.Barrier()
    return read_scene(str(path))


@pytest.fixture(scope="module")
def tmp(tmp_path_factory):
    path = tmp_path_factory.mktemp("rough") if COMM.rank == 0 else None
    return COMM.bcast(path)


def _run(scene, record=None):
    """The scene's run (Simulation), its summary, its foot radius (the largest current r of
    a boundary node within h = R / n_r of the anvil) and its contact radius (m)."""
    sim = build(scene, {"out": None, "quiet": True, "plots": False, "fields": False})
    if record is not None:
        record(sim)
    s = sim.run(extra=sim.scene_figures)
    model, u = sim.model, sim.integrator.u_owned
    h = scene.mesh.params["radius"] / N_R
    nodes = boundary_nodes(model.V, model.n_owned // 2)
    wall = sim.contacts[-1]
    return (sim, s, foot_radius(nodes, model.node_xy, u, scene.wall.z, h, COMM),
            contact_radius(wall, model.node_xy, u, COMM))


@pytest.mark.parametrize("method", ["film", "dme"])
def test_foot_radius_falls_with_mu_and_the_ledger_closes(tmp, method):
    feet = []
    for mu in MUS:
        sim, s, foot, contact = _run(_scene(tmp, method, mu))
        assert s["status"] == "completed"
        balance = np.abs(sim.energy.data()["balance_error"]).max()
        assert balance <= ledger(s["n_steps"], s["n_dofs"]) * s["energy_initial"]
        assert 0.0 < contact <= foot * (1 + 1e-12)
        w = s["friction"][0] if mu != "0.0" else {}
        if mu != "0.0":
            assert w["slip_work"] >= 0.0 and w["peak_tangential_force"] > 0.0
        if mu == '"stick"':
            # nothing slips: D = sum h |lambda_t| |w+| is the round-off of w+ = 0, at most
            # 4 EPS v0 (FILM's stick velocity rounds on the predicted ones, below v0) per
            # active row and step, on the peak force and the longest step
            bound = (s["n_steps"] * s["contact"]["n_constraints"] * s["dt_range"][1]
                     * w["peak_tangential_force"] * 4 * EPS * 227.0)
            assert w["slip_work"] <= bound
        if COMM.rank == 0:
            print(f"{method} mu = {mu}: foot {foot * 1e3:.4f} mm, contact {contact * 1e3:.4f} "
                  f"mm, face {s['final_face_radius'] * 1e3:.4f} mm, length "
                  f"{s['final_length'] * 1e3:.4f} mm, slip work "
                  f"{w.get('slip_work', 0.0):.4g} J, balance {balance:.2g} J")
        feet.append(foot)
    assert all(a > b for a, b in zip(feet, feet[1:])), feet


def _recorder(store: dict, face_rows: bool):
    """Wrap the run's wall step: keep (u, v) after every step and, for the contact run,
    the first step at which a face node is not active (its normal multiplier would be
    tensile: the held face would pull it)."""
    def attach(sim):
        wall = sim.contacts[-1]
        u_owned, v_owned = sim.integrator.u_owned, sim.integrator.v_owned
        # (the mesh's face lies at Z = 0 within the rounding of its generator)
        length = sim.model.length_scale
        face = np.flatnonzero(np.abs(np.asarray(wall.constraints.b)) <= 1e-9 * length)
        step = wall.step

        def recorded(*args):
            w = step(*args)
            n = len(store["u"])
            if n < store["limit"]:
                store["u"].append(u_owned.copy())
                store["v"].append(v_owned.copy())
                if face_rows and store["lift"] is None and not wall.active[face].all():
                    store["lift"] = n  # (0-based: the step n + 1)
                    store["t"] = sim.integrator.t
                    off = face[~wall.active[face]]
                    store["r"] = float(np.asarray(wall.constraints.r)[off].max())
            return w
        wall.step = recorded
        store["face"] = face
    return attach


@pytest.mark.parametrize("method", ["film", "dme"])
def test_full_stick_is_a_held_face_until_a_face_node_would_pull(tmp, method):
    scene = _scene(tmp, method, '"stick"', t_end=20e-6)
    stick = {"u": [], "v": [], "lift": None, "limit": 10 ** 6}
    _run(scene, _recorder(stick, True))
    assert stick["lift"] is not None, "no face node left the wall in 20 us"
    k = stick["lift"]
    held = {"u": [], "v": [], "lift": None, "limit": k + 1}
    _run(_scene(tmp, method, '"stick"', t_end=20e-6, held=True), _recorder(held, False))
    # before the lift the two runs take the same arithmetic but for the face nodes' z
    # correction (DME: u_z = 0, v = 0 exactly; FILM: u~ + h^2 lambda / m, zero within
    # the rounding of u~), so they agree to the round-off of the steps: 32 roundings a
    # step on the state's scale (roundoff.ledger's count), k steps
    u_scale = max(np.abs(held["u"][k - 1]).max(initial=0.0), 1e-300)
    v_scale = 227.0
    du = max(np.abs(a - b).max(initial=0.0) for a, b in zip(stick["u"][:k], held["u"][:k]))
    dv = max(np.abs(a - b).max(initial=0.0) for a, b in zip(stick["v"][:k], held["v"][:k]))
    du, dv = COMM.allreduce(du, op=MPI.MAX), COMM.allreduce(dv, op=MPI.MAX)
    if COMM.rank == 0:
        print(f"{method}: a face node first lets go at step {k + 1} (t = {stick['t'] * 1e6:.4g} "
              f"us, the node at R = {stick['r'] * 1e3:.3g} mm); before it |du| {du:.3g} m of "
              f"{u_scale:.3g}, |dv| {dv:.3g} m/s")
    assert du <= 32 * k * EPS * u_scale and dv <= 32 * k * EPS * v_scale
    # and at that step the held face pulls: the runs part
    dk = COMM.allreduce(float(np.abs(stick["v"][k] - held["v"][k]).max(initial=0.0)), op=MPI.MAX)
    assert dk > 32 * k * EPS * v_scale
