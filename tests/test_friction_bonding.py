"""Full stick is bonding (docs/friction.md 8).

A steel striker (ν = 0.3) at 5 m/s meets an aluminium target (ν = 0.33) of the same
radius on matched faces touching at t = 0; the Poisson ratios differ, so the faces want
to slide radially. With `friction = "stick"` (FILM, and DME with e = 0 and mass-weighted
positions) every pair moves as one in both components: the run is one two-material bar
whose interface nodes are shared (a conforming mesh of the same cells), started with
the shared nodes at the momentum average m_s v0 / (m_s + m_t) (m_s, m_t: the node's
lumped masses in each body). Oracles, up to the step before the first pair opens (its
normal multiplier would be tensile; the step is printed):

* the kinetic and strain energies and σ_zz at a point in each body agree within the
  spread of a one-ulp change of v0 (the two runs sum their forces in other orders);
* the contact run's extra loss is its activation loss: its contact work is
  -(E0 - E0_bonded), the energy the first step's merge takes, within the ledger's
  round-off (roundoff.ledger);
* with μ = 0.3 instead, a pair slips (the bonded interface's shear is singular at the rim);
* the penalty's stick (normal and tangential springs at beta) is FILM's at beta = 1 and
  differs from it by a first-order term in |1 - beta| below (a halved sequence).
"""
import numpy as np
import pytest
from mpi4py import MPI

from impact_fenics import meshing
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.contact import DME, FILM, Penalty, pair_surfaces
from impact_fenics.materials import STEEL, LinearElastic
from impact_fenics.simulation import Settings, Simulation
from roundoff import assert_within_spread, ledger, one_ulp

COMM = MPI.COMM_WORLD
ALU = LinearElastic(E=70e9, nu=0.33, density=2700.0)
R, L, H, V0, DT, T_END = 0.01, 0.04, 0.002, 5.0, 9e-8, 3e-5
POINTS = {"s": (0.005, -0.01), "t": (0.005, 0.01)}  # (r, z) m, in the striker and the target


def _bonded_mesh():
    """The two bars of meshing.coaxial_bars (structured, the same cells) sharing the
    interface line z = 0: one conforming mesh of two cell groups."""
    n_r, n_z = round(R / H), round(L / H)

    def build(gmsh):
        geo = gmsh.model.geo
        p = [geo.addPoint(0, -L, 0, H), geo.addPoint(R, -L, 0, H), geo.addPoint(R, 0, 0, H),
             geo.addPoint(0, 0, 0, H), geo.addPoint(R, L, 0, H), geo.addPoint(0, L, 0, H)]
        # the interface runs from the axis outward, as the target's bottom in coaxial_bars
        # (the transfinite pattern follows the curves' directions)
        c = [geo.addLine(p[0], p[1]), geo.addLine(p[1], p[2]), geo.addLine(p[3], p[2]),
             geo.addLine(p[3], p[0]), geo.addLine(p[2], p[4]), geo.addLine(p[4], p[5]),
             geo.addLine(p[5], p[3])]
        s1 = geo.addPlaneSurface([geo.addCurveLoop([c[0], c[1], -c[2], c[3]])])
        s2 = geo.addPlaneSurface([geo.addCurveLoop([c[2], c[4], c[5], c[6]])])
        for k in (0, 2, 5):
            geo.mesh.setTransfiniteCurve(c[k], n_r + 1)
        for k in (1, 3, 4, 6):
            geo.mesh.setTransfiniteCurve(c[k], n_z + 1)
        geo.mesh.setTransfiniteSurface(s1, "Alternate")
        geo.mesh.setTransfiniteSurface(s2, "Alternate")
        geo.synchronize()
        for dim, ents, name, tag in ((2, [s1], "striker", 1), (2, [s2], "target", 2),
                                     (1, [c[0]], "striker_end", 11), (1, [c[5]], "target_end", 16),
                                     (1, [c[3], c[6]], "axis", 17)):
            gmsh.model.addPhysicalGroup(dim, ents, tag)
            gmsh.model.setPhysicalName(dim, tag, name)
        gmsh.option.setNumber("Mesh.Algorithm", 6)
        gmsh.model.mesh.generate(2)

    return meshing._to_dolfinx(COMM, build, {"scene": "bonded_bars"})


def _settings() -> Settings:
    return Settings(dt=DT, t_end=T_END, energy_every=1, history_every=1, quiet=True)


def _contact_run(method, friction, v0=V0):
    tmesh = meshing.coaxial_bars(radius=R, striker_length=L, target_length=L, h=H,
                                 structured=True, comm=COMM)
    model = DeformableModel(tmesh, [Body("striker", STEEL), Body("target", ALU)])
    sim = Simulation(model, _settings(), initial_velocity={"striker": (0.0, v0)})
    sim.add_contact(pair_surfaces(model, "striker_contact", "target_contact"), method)
    sim.contacts[0].set_friction(friction)
    for name, point in POINTS.items():
        sim.add_probe(f"szz_{name}", point, "sigma_zz")
    c = sim.contacts[0]
    n = c.n  # the pairs' lumped masses (kg), by radius: lower = striker, upper = target
    masses = (c.r.copy(), c.mass[:n].copy(), c.mass[n:2 * n].copy())
    summary = sim.run()
    summary["e0"] = 0.5 * sim.body_mass["striker"] * v0 ** 2  # J, the initial energy
    return sim.history.data(), sim.energy.data(), summary, masses


def _bonded_run(masses):
    model = DeformableModel(_bonded_mesh(), [Body("striker", STEEL), Body("target", ALU)])
    sim = Simulation(model, _settings(), initial_velocity={"striker": (0.0, V0)})
    r, m_s, m_t = masses
    # the shared interface nodes start at the momentum average of the two bodies' nodes
    # (every owned node: a rank may own an interface node without a local cell of one body)
    z_dofs = np.union1d(model.body_dofs("striker", 1), model.body_dofs("target", 1))
    xy = model.dof_coordinates(z_dofs)
    on_face = np.flatnonzero(np.abs(xy[:, 1]) <= 1e-12 * L)
    v = sim.integrator.v_owned
    for k in on_face:
        i = int(np.argmin(np.abs(r - xy[k, 0])))
        assert abs(r[i] - xy[k, 0]) <= 1e-9 * R
        v[z_dofs[k]] = m_s[i] * V0 / (m_s[i] + m_t[i])
    for name, point in POINTS.items():
        sim.add_probe(f"szz_{name}", point, "sigma_zz")
    e0 = COMM.allreduce(0.5 * float(np.dot(sim.integrator.mass * v, v)))
    sim.run()
    return sim.history.data(), sim.energy.data(), e0


@pytest.fixture(scope="module", params=["film", "dme"])
def runs(request):
    make = {"film": lambda: FILM(), "dme": lambda: DME(restitution=0.0)}[request.param]
    contact = _contact_run(make(), "stick")
    ulp = _contact_run(make(), "stick", one_ulp(V0))
    bonded = _bonded_run(contact[3])
    return contact, ulp, bonded


def test_full_stick_is_bonding(runs):
    (hc, ec, summary, masses), (hu, eu, _, _), (hb, eb, e0_b) = runs
    n_pairs = masses[0].size
    opened = np.flatnonzero(hc["n_active"] < n_pairs)
    first = int(hc["step"][opened[0]]) if opened.size else int(hc["step"][-1]) + 1
    if COMM.rank == 0:
        print(f"\nfirst step with a pair open: {first} of {int(hc['step'][-1])}")
    keep = hc["step"] < first  # the steps before: the bonded interface holds
    assert keep.sum() >= 20  # a real stretch of the impact (at least 20 steps)
    n = int(keep.sum())
    for col in ("szz_s", "szz_t"):
        assert_within_spread(hc[col][keep], hb[col][keep], hu[col][keep], n, col)
    rows = ec["step"] < first
    for col in ("kinetic", "strain"):
        assert_within_spread(ec[col][rows], eb[col][rows], eu[col][rows], n, col)
    # the contact run's extra loss: its contact work is the first step's merge, E0 - E0_b
    e0_c = summary["e0"]
    scale = abs(e0_c)
    bound = ledger(int(hc["step"][-1]), summary["n_dofs"]) * scale
    assert abs(ec["contact_work"][rows][-1] + (e0_c - e0_b)) <= bound
    assert abs(ec["activation_loss"][rows][-1] - (e0_c - e0_b)) <= bound
    assert not np.any(hc["n_slip"])


def test_finite_mu_slips_at_the_rim():
    """μ = 0.3 instead of stick: some pair slips (the bonded interface's shear is singular
    at the rim, where the cone is cut first)."""
    h, _, _, masses = _contact_run(FILM(), 0.3)
    assert np.any(h["n_slip"] > 0)


def _penalty_run(beta: float):
    """The stick run with the penalty at beta: the normal spring scaled to beta
    (Penalty(beta_target=beta), p = beta / d per pair) and the tangential one too (the
    scaled k_t = m_red / (h h_n), beta_t = 1, times beta at every set_step)."""
    orig_add = Simulation.add_contact

    def add_contact(sim, *args, **kwargs):
        c = orig_add(sim, *args, **kwargs)
        set_friction = c.set_friction

        def with_beta(*a, **k):
            set_friction(*a, **k)
            t = c.friction
            set_step = t.set_step

            def scaled_step():
                set_step()
                t.k_t *= beta  # in place: the kernels' bound arguments hold this array

            t.set_step = scaled_step
            scaled_step()

        c.set_friction = with_beta
        return c

    Simulation.add_contact = add_contact
    try:
        return _contact_run(Penalty("scaled", beta_target=beta), "stick")
    finally:
        Simulation.add_contact = orig_add


DELTAS = (0.4, 0.2, 0.1, 0.05)  # |1 - beta|, halved


def test_penalty_bonding_converges_with_one_minus_beta():
    """The penalty's stick (normal and tangential springs at beta <= 1) against exact
    bonding (FILM's stick, which is the bonded bar: test_full_stick_is_bonding), up to the
    step before FILM's first pair opens: at beta = 1 the penalty is FILM (p = 1 / d and
    k_t = m_red / (h h_n) close the gap and the slip in one step), σ_zz at the two points
    within the spread of a one-ulp change of v0; below it the largest difference of σ_zz
    is first order in |1 - beta| (the springs' recurrences leave (1 - beta) of the step's
    gap and slip). For δ = 0.4, 0.2, 0.1, 0.05 the observed order log2(d(2δ) / d(δ)) tends
    to 1 with its excess over 1 falling (a δ + b δ^2: the excess is O(δ)); at the finest
    pair it is within 0.1 of 1 (the δ^2 term's share at δ = 0.1, measured at about half
    the excess of the pair before). No pair opens or slips in any of them."""
    film, film_ulp = _contact_run(FILM(), "stick"), _contact_run(FILM(), "stick", one_ulp(V0))
    h0, hu = film[0], film_ulp[0]
    n_pairs = film[3][0].size
    opened = np.flatnonzero(h0["n_active"] < n_pairs)
    first = int(h0["step"][opened[0]]) if opened.size else int(h0["step"][-1]) + 1
    keep = h0["step"] < first
    n = int(keep.sum())
    cols = ("szz_s", "szz_t")
    scale = max(np.abs(h0[c][keep]).max() for c in cols)
    h1 = _penalty_run(1.0)[0]
    for c in cols:
        assert_within_spread(h1[c][keep], h0[c][keep], hu[c][keep], n, c)
    diffs = []
    for delta in DELTAS:
        h = _penalty_run(1.0 - delta)[0]
        assert np.all(h["n_active"][keep] == n_pairs) and not np.any(h["n_slip"])
        diffs.append(max(np.abs(h[c][keep] - h0[c][keep]).max() for c in cols) / scale)
    orders = np.log2(np.array(diffs[:-1]) / np.array(diffs[1:]))
    if COMM.rank == 0:
        print("\npenalty bonding: |1 - beta| " + ", ".join(f"{d:g}" for d in DELTAS)
              + "; max |Δσ_zz| / max |σ_zz| " + ", ".join(f"{d:.3e}" for d in diffs)
              + "; observed orders " + ", ".join(f"{p:.3f}" for p in orders))
    assert np.all(np.diff(diffs) < 0.0)
    excess = orders - 1.0
    assert np.all(excess > 0.0) and np.all(np.diff(excess) < 0.0)
    assert excess[-1] <= 0.1
