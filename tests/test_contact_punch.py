"""A rigid punch on a block: the coupled FILM problem, DME's rigid cluster, and their motion.

Oracles: the complementarity conditions themselves (lambda >= 0, g >= 0,
lambda g = 0), an independent solver of the same problem (SciPy's NNLS on the
equivalent quadratic program), exact agreement of FILM and DME while the
active set holds, and the energy ledger.

Round-off (tests/roundoff.py): a linear solve of S (n active constraints, condition
number kappa(S)) errs by at most n roundings of its backward error times kappa(S), so
two solvers agree within 2 n kappa(S) roundings; whole runs within the steps x the
spread of the run under a one-ulp change of the load's peak (the punch starts at rest).
"""
import numpy as np
import pytest
from scipy.optimize import nnls

from impact_fenics import loads, meshing
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.contact import DME, FILM, RigidBody, rigid_face
from impact_fenics.contact.film import solve_dense, solve_fast
from impact_fenics.materials import LinearElastic
from impact_fenics.simulation import Settings, Simulation
from roundoff import assert_within_spread, ledger, one_ulp, rounding

BLOCK = dict(width=1.5, depth=0.3, h_surface=0.02, grading=0.3, breaks=((0.5, 25), (1.0, 25)))


def _problem(n, tensile, seed=0):
    """Predicted gaps g~ (m), d (m/N) and kappa (m/N) like a light punch on heavy nodes.

    With ``tensile`` a third of the penetrating candidates penetrate so little that
    the punch, pushed back by the others, opens them: their multipliers from the
    naive solve on {g~ < 0} would be tensile."""
    rng = np.random.default_rng(seed)
    dt, m_p = 3.64e-7, 0.1
    m = rng.uniform(0.2, 5.0, n)  # ring masses (kg)
    d = dt ** 2 / m
    kappa = dt ** 2 / m_p
    gap = -rng.uniform(1e-5, 2e-5, n)
    if tensile:
        gap[: n // 3] = -rng.uniform(1e-9, 1e-8, n // 3)
        gap[n // 3: n // 2] = rng.uniform(0, 1e-5, n // 2 - n // 3)  # open
    return gap, d, kappa


def _qp_oracle(gap, d, kappa):
    """min 1/2 l'Sl + g'l, l >= 0 (the LCP of FILM) as NNLS: S = L L', min |L'l + L^-1 g|."""
    S = np.diag(d) + kappa
    L = np.linalg.cholesky(S)
    return nnls(L.T, -np.linalg.solve(L, gap), maxiter=50 * gap.size)[0]


@pytest.mark.parametrize("tensile", [False, True])
@pytest.mark.parametrize("n", [5, 107, 610])
def test_fast_and_dense_film_agree_and_solve_the_complementarity_problem(n, tensile):
    gap, d, kappa = _problem(n, tensile)
    fast = solve_fast(gap, d, kappa, np.empty(n))
    dense = solve_dense(gap, d, kappa, np.empty(n))
    scale = np.abs(dense).max()
    active = dense > 0
    cond = np.linalg.cond(np.diag(d[active]) + kappa)  # S on the loaded set
    solves = rounding(2 * n * cond, scale)  # two solvers (the QP oracle: another)
    assert np.abs(fast - dense).max() <= solves
    g = gap + d * fast + kappa * fast.sum()
    # g: a sum of n forces times kappa and two products, on the largest of its terms
    g_round = rounding(n + 4, np.abs(gap).max() + (d * fast).max() + kappa * fast.sum())
    assert fast.min() >= 0.0
    assert g.min() >= -g_round
    assert np.abs(fast * g).max() <= g_round * scale
    if tensile:  # some candidates with g~ < 0 carry no force
        assert np.any((gap < 0) & (fast == 0.0))
    if n <= 107:
        assert np.abs(fast - _qp_oracle(gap, d, kappa)).max() <= solves


def test_film_pairs_are_closed_form():
    gap = np.array([-1e-6, 2e-6, -3e-7])
    d = np.array([1e-12, 2e-12, 4e-12])
    # kappa = 0: each force is -g~ / d, one division (and 1/d: two roundings)
    assert np.allclose(solve_fast(gap, d, 0.0, np.empty(3)), [1e6, 0.0, 7.5e4], atol=0,
                       rtol=rounding(2))


def _punch(method, profile=None, radius=0.5, peak=200e6):
    tmesh = meshing.punch_block(**BLOCK)
    model = DeformableModel(tmesh, [Body("block", LinearElastic())])
    pulse = loads.Trapezoid(peak=peak, t_rise=1e-5, t_fall=9e-5, t_end=1e-4)
    area = np.pi * radius ** 2
    punch = RigidBody("punch", 0.1, force=lambda t: -area * pulse(t))
    sim = Simulation(model, Settings(dt=3.64e-7, n_steps=400, output_every=20, quiet=True),
                     fixed=[model.facet_dofs("bottom", 1)])
    sim.add_contact(rigid_face(model, "surface", radius if profile is None else 1.0, "punch",
                               profile=profile), method, rigid=punch)
    summary = sim.run()
    return summary, sim.history.data()


# solve_dense (contact/film.py) accepts an unloaded constraint with g >= -1e-14 m (its
# tolerance is 1e-14 max(1 m, max|g~|): absolute for gaps below a metre)
DENSE_ACCEPT = 1e-14


def _penetration_bound(hist, dense=False) -> float:
    """Round-off of a committed gap b + u_punch - u_node (m) after the correction that
    closed it: a few roundings (16) of displacements up to the punch's and of the
    profile's b, no larger than the punch's travel at an active node; the dense solver's
    acceptance on top."""
    return rounding(16, 2 * np.abs(hist["punch_u"]).max()) + (DENSE_ACCEPT if dense else 0.0)


@pytest.fixture(scope="module")
def flat():
    runs = {name: _punch(m) for name, m in (("fast", FILM("fast")), ("dense", FILM("dense")),
                                            ("dme", DME()))}
    runs["ulp"] = _punch(FILM("fast"), peak=one_ulp(200e6))  # the spread of a whole run
    return runs


@pytest.fixture(scope="module")
def curved():
    sphere = 5.0  # m: b(r) = r^2 / (2 R), new nodes come into contact as the punch sinks
    return {name: _punch(m, profile=lambda r: r ** 2 / (2 * sphere))
            for name, m in (("film", FILM()), ("dme", DME()))}


@pytest.mark.parametrize("name", ["fast", "dense", "dme"])
def test_no_committed_penetration(flat, name):
    summary, hist = flat[name]
    assert summary["contact"]["max_penetration"] <= _penetration_bound(hist, name == "dense")
    assert hist["n_active"].max() == 26  # the nodes with r <= 0.5 m
    assert summary["energy_balance_error_rel"] <= ledger(400, summary["n_dofs"])


def test_fast_and_dense_film_give_the_same_run(flat):
    """Two solvers of one problem at every step: within the 400 steps x the spread of the
    fast solver's run under a one-ulp change of the load's peak."""
    u_fast, u_dense = flat["fast"][1]["punch_u"], flat["dense"][1]["punch_u"]
    assert_within_spread(u_dense, u_fast, flat["ulp"][1]["punch_u"], 400, "punch_u")


def test_film_and_dme_coincide_while_the_active_set_holds(flat):
    # A flat punch starting in contact: until the first release (unloading) no
    # node activates with an open gap, and the rigid cluster of DME and the
    # multipliers of FILM give one motion.
    h_film, h_dme = flat["fast"][1], flat["dme"][1]
    # Their expressions differ, so over the hold they agree within its steps x the
    # spread of the FILM run under a one-ulp change of the load's peak.
    held = slice(0, int(np.argmax(np.diff(h_film["n_active"]) < 0)))
    assert held.stop > 200  # the hold lasts to the unloading ramp (90 us = step 247)
    h_ulp = flat["ulp"][1]
    for key in ("punch_u", "punch_force"):
        assert_within_spread(h_dme[key][held], h_film[key][held], h_ulp[key][held],
                             held.stop, key)
    # while unloading, nodes part and touch again with open gaps: there they differ,
    # slightly (the paper's "barely noticeable difference during unloading"): by
    # less than the punch moves in one step, the scale of a re-contact
    one_step = np.abs(np.diff(h_film["punch_u"])).max()
    assert np.abs(h_film["punch_u"] - h_dme["punch_u"]).max() < one_step


def test_film_and_dme_differ_at_activations(curved):
    (s_film, h_film), (s_dme, h_dme) = curved["film"], curved["dme"]
    # both keep the constraints and balance energy to round-off
    for s, h in ((s_film, h_film), (s_dme, h_dme)):
        assert s["contact"]["max_penetration"] <= _penetration_bound(h)
        assert s["energy_balance_error_rel"] <= ledger(400, s["n_dofs"])
    # FILM closes a gap with an impulse and dissipates; DME moves the arriving
    # node onto the punch (a jump against its loaded neighbours) and gains energy
    assert s_film["energy"]["activation_loss"] > 0
    assert s_dme["energy"]["activation_loss"] < 0
    u_film, u_dme = h_film["punch_u"], h_dme["punch_u"]
    # and their motions differ by far more than round-off
    assert np.abs(u_film - u_dme).max() > 1e-6 * np.abs(u_film).max()
