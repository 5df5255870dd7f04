"""Path-dependent bodies in the explicit loop: J2 at the stiffness rule's points.

Oracles: the linear path (a J2 body that never yields is the linear body, to
round-off), the closed-form uniaxial-strain plastic wave (elastic precursor and
plastic front), the discrete energy identities of the scheme, the equality of
two independent implementations of f_int (a fused kernel and dolfinx's own
assembly), and the serial run as the oracle of the parallel one.

Round-off (tests/roundoff.py): one step from one state within a count of roundings;
whole runs within the steps x the spread of the reference run under a one-ulp change
of its start (the striker's velocity, or the load's peak for a bar loaded from rest);
the ledgers within roundoff.ledger.
"""
import math

import numpy as np
from mpi4py import MPI

from impact_fenics import loads, meshing, scenes
from impact_fenics.bodies import Body, DeformableModel
from impact_fenics.contact import pair_surfaces
from impact_fenics.internal_force.quadrature import QuadratureForce
from impact_fenics.materials import STEEL
from impact_fenics.materials.j2 import J2
from impact_fenics.simulation import Settings, Simulation
from roundoff import assert_runs_agree, assert_within_spread, ledger, one_ulp, rounding

NEVER = 1e15  # a yield stress (Pa) above any stress these runs reach


# ---------------------------------------------------------------- elastic limit
def test_j2_that_never_yields_is_the_linear_body():
    """Same bar, same pulse: steel vs J2 with yield stress 1e15 Pa, fast and generic paths.
    The state lives at the stiffness rule's points, so f_int = K u to round-off: by other
    expressions at every step, so within the 150 steps x the spread of the linear run
    under a one-ulp change of the pulse's peak (class (c))."""
    def run(material, path="fast", peak=100e6):
        sim = scenes.elastic_bar(Settings(dt=1e-6, n_steps=150, output_every=10, quiet=True,
                                          f_int_path=path),
                                 h=0.01, length=0.5, nu=0.3, material=material, peak=peak)
        sim.add_probe("s", (0.02, 0.2), "sigma_zz")
        sim.add_probe("vm", (0.04, 0.05), "von_mises")
        sim.add_probe("uz", (0.02, 0.2), "u_z")
        sim.run()
        return sim.history.data(), sim.energy.data()

    ref_h, ref_e = run(None)
    ulp_h, ulp_e = run(None, peak=one_ulp(100e6))
    for path in ("fast", "generic"):
        h, e = run(J2(E=STEEL.E, nu=0.3, density=STEEL.density, yield_stress=NEVER), path)
        for col in ("s", "vm", "uz"):
            assert_within_spread(h[col], ref_h[col], ulp_h[col], 150, f"{path}: {col}")
        for col in ("kinetic", "strain", "external_work"):
            assert_within_spread(e[col], ref_e[col], ulp_e[col], 150, f"{path}: {col}")
        assert np.all(e["plastic_work"] == 0.0)  # no point yields: no term is ever added


def test_mixed_run_elastic_striker_on_j2_target_matches_linear():
    """Bar impact with DME: a linear striker on a J2 target that never yields equals the
    all-linear run (contact, ledger and outputs see one velocity update): within the 200
    steps x the spread of the all-linear run with the striker one ulp faster (class (c));
    both ledgers close."""
    def run(target, v0=5.0):
        tm = meshing.coaxial_bars(radius=0.05, striker_length=0.2, target_length=0.25, h=0.025)
        model = DeformableModel(tm, [Body("striker", STEEL), Body("target", target)])
        sim = Simulation(model, Settings(dt=1e-6, n_steps=200, output_every=20, quiet=True),
                         initial_velocity={"striker": (0.0, v0)})
        sim.add_contact(pair_surfaces(model, "striker_contact", "target_contact"),
                        scenes.make_method("dme"))
        sim.add_probe("s", (0.05, 0.1), "sigma_zz")
        sim.run()
        return sim.history.data(), sim.energy.data(), sim.summary

    ref_h, ref_e, ref_s = run(STEEL)
    ulp_h, ulp_e, _ = run(STEEL, one_ulp(5.0))
    h, e, s = run(J2(E=STEEL.E, nu=STEEL.nu, density=STEEL.density, yield_stress=NEVER))
    assert np.array_equal(h["n_active"], ref_h["n_active"])
    for col in ("s", "contact_force"):
        assert_within_spread(h[col], ref_h[col], ulp_h[col], 200, col)
    scale = np.abs(ref_e["total"]).max()
    for col in ("kinetic", "strain", "contact_work"):
        assert_within_spread(e[col], ref_e[col], ulp_e[col], 200, col, scale)
    for summary in (ref_s, s):
        assert summary["energy_balance_error_rel"] <= ledger(200, summary["n_dofs"])


# ---------------------------------------------------------------- generic == fast
def test_generic_and_fast_f_int_agree_to_round_off():
    """Both paths from the same plastic state and displacement: the same f_int and the same
    updated state. The displacement is a smooth field large enough to yield most points.

    Round-off: a point's stress takes about 48 roundings on each path (strain from the
    gradients, the trial stress, its deviator and norm, the radial return), 96 between
    the two, on the scale of the largest |sigma|; the plastic multiplier
    (q_tr - sigma_y) / (3 mu + H) carries that error of q_tr divided by 3 mu + H, on each
    of the three steps; f_int at a node sums at most 6
    cells x 3 points of B' sigma w (4 roundings each, 18 terms), terms no larger than
    the largest |f_int| (that of a boundary node, where they do not cancel)."""
    tm = meshing.bar(radius=0.05, length=0.2, h=0.01, structured=False)
    mat = J2(E=200e9, nu=0.3, yield_stress=200e6, hardening=1e9)
    model = DeformableModel(tm, [Body("bar", mat)])
    from dolfinx import fem

    u = fem.Function(model.V)
    u.interpolate(lambda x: np.stack([2e-3 * x[0] * np.sin(20 * x[1]),
                                      3e-3 * x[1] ** 2 + 1e-3 * x[0]]))
    coef = np.zeros(model.n_owned)
    forces = {p: QuadratureForce(model, "bar", u, 1e-6, coef, p) for p in ("fast", "generic")}
    point = 96  # roundings of a point's stress, both paths
    for k, scale in enumerate((1.0, 0.6, 1.3)):  # three steps: load, unload, reload
        u.x.array[:] *= scale
        f = {p: q.compute().copy() for p, q in forces.items()}
        fs, fg = f["fast"], f["generic"]
        amax = MPI.COMM_WORLD.allreduce(np.abs(fg).max(), op=MPI.MAX)
        diff = MPI.COMM_WORLD.allreduce(np.abs(fs - fg).max(), op=MPI.MAX)
        assert diff <= rounding((point + 4) * 18, amax)
        a, b = forces["fast"].qs, forces["generic"].qs
        s_max = np.abs(b.sigma).max()
        assert np.abs(a.sigma - b.sigma).max() <= rounding(point, s_max)
        assert np.abs(a.state - b.state).max() <= (k + 1) * rounding(point, s_max) / (
            3 * mat.mu + mat.hardening)
    yielded = MPI.COMM_WORLD.allreduce(int((a.state[..., 0] > 0).sum()))
    total = MPI.COMM_WORLD.allreduce(a.state[..., 0].size)
    assert yielded > total // 2


# ---------------------------------------------------------------- energy
def test_energy_split_over_ten_thousand_plastic_steps():
    """A short J2 bar, clamped at its far end, under a held pressure above its elastic limit:
    waves bounce for 10^4 steps and keep yielding it. The ledger E = 1/2 v'Mv + psi_e + W_p
    balances the external work, and the deformation work sum 1/2 (f^n + f^{n+1}) . du equals
    d psi_e + W_p, both to the round-off of a ledger over 10^4 steps (roundoff.ledger)."""
    mat = J2(E=200e9, nu=0.3, density=7850.0, yield_stress=200e6, hardening=5e9)
    tm = meshing.bar(radius=0.02, length=0.1, h=0.01, structured=True)
    model = DeformableModel(tm, [Body("bar", mat)])
    pulse = loads.Trapezoid(peak=700e6, t_rise=2e-5, t_fall=6e-4, t_end=8e-4)
    sim = Simulation(model, Settings(cfl=0.5, n_steps=10_000, output_every=500, quiet=True,
                                     fields=False),
                     fixed=[model.facet_dofs("free_end", 1)],
                     loads=[loads.SurfaceLoad(model, "loaded_end", pulse)])
    s = sim.run()
    e = sim.energy.data()
    bound = ledger(10_000, s["n_dofs"])
    assert np.abs(e["balance_error_rel"]).max() <= bound
    psi0 = e["strain"][0]
    split = e["deformation_work"] - (e["strain"] - psi0) - e["plastic_work"]
    assert np.abs(split).max() <= bound * np.abs(e["deformation_work"]).max()
    # plasticity is active and dissipates a real share of the work put in
    assert e["plastic_work"][-1] > 0.1 * e["external_work"][-1] > 0.0
    assert np.all(np.diff(e["plastic_work"]) >= 0.0)


# ---------------------------------------------------------------- the plastic wave
def _wave(h, comm=MPI.COMM_WORLD, P=600e6, L=2.0, t_end=3e-4, probes=(), mat=None):
    if mat is None:
        mat = J2(E=200e9, nu=0.3, density=7850.0, yield_stress=200e6, hardening=10e9)
    tm = meshing.bar(radius=2 * h, length=L, h=h, structured=True, comm=comm)
    model = DeformableModel(tm, [Body("bar", mat)])
    sim = Simulation(model, Settings(cfl=0.5, t_end=t_end, output_every=50, quiet=True,
                                     fields=False),
                     fixed=[model.body_dofs("bar", 0)],  # u_r = 0 on every node: uniaxial strain
                     loads=[loads.SurfaceLoad(model, "loaded_end", loads.Constant(P))])
    for name, point, quantity in probes:
        sim.add_probe(name, point, quantity)
    return sim, mat


def _profiles(sim, h, L):
    """Mass-weighted mean v_z per node row z = k h, and the weighted mean sigma_zz of the
    quadrature points per band [k h, (k+1) h), summed over ranks."""
    model, integ, comm = sim.model, sim.integrator, sim.comm
    z = model.node_xy[: model.n_owned // 2, 1]
    rows = np.round(z / h).astype(int)
    nb = int(round(L / h)) + 1
    m, v = integ.mass[1::2], integ.v_owned[1::2]
    mv = comm.allreduce(np.bincount(rows, m * v, nb), op=MPI.SUM)
    mm = comm.allreduce(np.bincount(rows, m, nb), op=MPI.SUM)
    f = integ.nonlinear[0]
    g = f.geometry
    zq = np.einsum("qi,ni->nq", g.N, model.node_xy[g.dofs][:, :, 1])
    band = np.minimum(np.floor(zq / h).astype(int), nb - 2).ravel()
    ws = comm.allreduce(np.bincount(band, (g.w * f.qs.sigma[:, :, 2]).ravel(), nb - 1), op=MPI.SUM)
    ww = comm.allreduce(np.bincount(band, g.w.ravel(), nb - 1), op=MPI.SUM)
    return np.arange(nb) * h, mv / mm, (np.arange(nb - 1) + 0.5) * h, ws / ww


def _front(z, y, level):
    """Last crossing of ``level`` from above, linearly interpolated (m)."""
    k = int(np.flatnonzero(y >= level)[-1])
    return z[k] + (y[k] - level) / (y[k] - y[k + 1]) * (z[k + 1] - z[k])


def test_uniaxial_strain_plastic_wave_two_meshes():
    """Pressure step P on a bar held at u_r = 0 everywhere (J2, linear hardening).

    Closed form (rate-independent, uniaxial strain): an elastic precursor of amplitude
    sigma_HEL = sigma_y (1 - nu)/(1 - 2 nu) at c_L = sqrt((lambda + 2 mu)/rho), particle
    velocity v1 = sigma_HEL/(rho c_L) behind it; a plastic front at
    c_p = sqrt((K + 4/3 mu H/(H + 3 mu))/rho) (the slope d sigma_zz/d eps_zz of the
    plastic branch) carrying the stress to P, with v2 = v1 + (P - sigma_HEL)/(rho c_p);
    behind it eps_bar_p = (2 mu e - sigma_y0)/(3 mu + H), e the strain where
    K e + 2/3 (sigma_y0 + H eps_bar_p) = P.

    Tolerances from the discretisation: with lumped mass the scheme is dispersive and a
    step front spreads into an Airy profile of width w = (h^2 c t)^(1/3); its half-level
    crossing sits a fraction of w behind c t, and the oscillations of its tail carry into
    the plateau means a relative error of order (h / c t)^(2/3) (= w / c t). Fronts are
    tested within w / 2 and plateau means within (h / c_L t)^(2/3); both shrink as h^(2/3)
    when h halves (measured: fronts 0.24-0.30 w; plateaus 0.1-0.7 of the bound). The
    plastic strain records the largest stress a point has seen, so a probe at z keeps
    the front's overshoot from when the front passed it, bounded by (h / z)^(2/3)
    (measured 0.75-0.82 of it)."""
    P, L, t_end = 600e6, 2.0, 3e-4
    for h in (0.01, 0.005):
        probe = ("ep", (h, 0.5), "eps_p_eq"), ("yl", (h, 0.5), "yielded"), \
                ("yl_ahead", (h, 1.9), "yielded")
        sim, mat = _wave(h, probes=probe)
        sim.run()
        t = sim.integrator.n * sim.integrator.dt
        zr, vz, zc, szz = _profiles(sim, h, L)
        szz = -szz  # compression
        lam, mu, K, rho = mat.lmbda, mat.mu, mat.bulk, mat.density
        H, sy = mat.hardening, mat.yield_stress
        cL = math.sqrt((lam + 2 * mu) / rho)
        cp = math.sqrt((K + 4 / 3 * mu * H / (H + 3 * mu)) / rho)
        s_hel = sy * (1 - mat.nu) / (1 - 2 * mat.nu)
        v1 = s_hel / (rho * cL)
        v2 = v1 + (P - s_hel) / (rho * cp)
        zL, zp = cL * t, cp * t
        w = (h * h * cL * t) ** (1 / 3)
        tol = (h / (cL * t)) ** (2 / 3)
        m = 1.5 * w  # plateaus: one and a half front widths away from each front
        behind = lambda z: (z > m) & (z < zp - m)  # noqa: E731
        between = lambda z: (z > zp + m) & (z < zL - m)  # noqa: E731
        assert abs(vz[behind(zr)].mean() / v2 - 1) <= tol
        assert abs(vz[between(zr)].mean() / v1 - 1) <= tol
        assert abs(szz[behind(zc)].mean() / P - 1) <= tol
        assert abs(szz[between(zc)].mean() / s_hel - 1) <= tol
        assert abs(_front(zr, vz, v1 / 2) - zL) <= w / 2
        assert abs(_front(zr, vz, (v1 + v2) / 2) - zp) <= w / 2
        assert abs(_front(zc, szz, s_hel / 2) - zL) <= w / 2
        assert abs(_front(zc, szz, (s_hel + P) / 2) - zp) <= w / 2
        # the plastic strain behind the front and the yielded flags, from the probes
        e = (P - 2 / 3 * sy + 2 / 3 * H * sy / (3 * mu + H)) / (K + 4 / 3 * mu * H / (3 * mu + H))
        ebar = (2 * mu * e - sy) / (3 * mu + H)
        hist = sim.history.data()
        # eps_bar_p keeps the memory of the front's overshoot when it passed the probe at
        # z = 0.5 m, i.e. after travelling z: the same bound with c t -> z
        assert abs(hist["ep"][-1] / ebar - 1) <= (h / 0.5) ** (2 / 3)
        assert hist["yl"][-1] == 1.0 and hist["yl_ahead"][-1] == 0.0
        assert sim.summary["plastic_dissipation"] > 0.0


def test_drucker_prager_uniaxial_strain_plastic_wave_two_meshes():
    """Pressure step P on a Drucker-Prager bar held at u_r = 0 everywhere.

    Closed form (tests/uniaxial_strain.py derives it; rate-independent, linear cohesion
    hardening h per unit of the deviatoric plastic strain): an elastic precursor of
    amplitude sigma_HEL = (K + 4 mu/3) k / (2 mu - K alpha_f) at c_L, a plastic front at
    c_p = sqrt(M_p / rho), M_p = K + 4 mu/3 - (2 mu - K alpha_f)(2 mu - K alpha_g) /
    (3 mu + K alpha_f alpha_g + h), carrying the axial stress to P; particle velocities
    v1 = sigma_HEL/(rho c_L) and v2 = v1 + (P - sigma_HEL)/(rho c_p). It exists only for
    alpha_f, alpha_g < 2 mu/K (= 1.5 at nu = 0.2): a cone matched to Mohr-Coulomb needs
    sin(phi) < 1 - 2 nu, and friction brings c_p close to c_L (the plateau between the
    fronts must be several front widths long), hence nu = 0.2, phi = 5 deg
    (alpha_f = 0.180), psi = 2 deg here (c_p = 0.77 c_L), not the granite of the
    bit-rock scene.

    Tolerances as in the J2 wave test, from the Airy width of a dispersed step front
    w = (h^2 c t)^(1/3): fronts within w / 2, plateau means within (h / c_L t)^(2/3); both
    shrink as h^(2/3) when h halves."""
    from impact_fenics.materials import DruckerPrager
    from uniaxial_strain import uniaxial_strain

    P, L, t_end = 600e6, 2.0, 3e-4
    mat = DruckerPrager(E=200e9, nu=0.2, density=7850.0, ucs=175e6, friction_angle=5.0,
                        dilatancy_angle=2.0, tensile_strength=50e6, hardening=10e9)
    cf = uniaxial_strain(mat)
    assert 0.1 * P < cf.sigma_hel < 0.7 * P and cf.c_plastic < 0.8 * cf.c_elastic
    rho = mat.density
    v1 = cf.sigma_hel / (rho * cf.c_elastic)
    v2 = v1 + (P - cf.sigma_hel) / (rho * cf.c_plastic)
    for h in (0.01, 0.005):
        sim, _ = _wave(h, P=P, L=L, t_end=t_end, mat=mat)
        sim.run()
        t = sim.integrator.n * sim.integrator.dt
        zr, vz, zc, szz = _profiles(sim, h, L)
        szz = -szz  # compression
        zL, zp = cf.c_elastic * t, cf.c_plastic * t
        w = (h * h * cf.c_elastic * t) ** (1 / 3)
        tol = (h / (cf.c_elastic * t)) ** (2 / 3)
        m = 1.5 * w
        behind = lambda z: (z > m) & (z < zp - m)  # noqa: E731
        between = lambda z: (z > zp + m) & (z < zL - m)  # noqa: E731
        assert abs(vz[behind(zr)].mean() / v2 - 1) <= tol
        assert abs(vz[between(zr)].mean() / v1 - 1) <= tol
        assert abs(szz[behind(zc)].mean() / P - 1) <= tol
        assert abs(szz[between(zc)].mean() / cf.sigma_hel - 1) <= tol
        assert abs(_front(zr, vz, v1 / 2) - zL) <= w / 2
        assert abs(_front(zr, vz, (v1 + v2) / 2) - zp) <= w / 2
        assert abs(_front(zc, szz, cf.sigma_hel / 2) - zL) <= w / 2
        assert abs(_front(zc, szz, (cf.sigma_hel + P) / 2) - zp) <= w / 2
        assert sim.summary["plastic_dissipation"] > 0.0


# ---------------------------------------------------------------- parallel
def test_plastic_wave_same_on_all_partitions():
    """COMM_WORLD vs COMM_SELF in one process: histories (plastic probes included), the
    ledger and the final plastic state agree: equal on one rank; on more, within the
    steps x the spread of the serial run under a one-ulp change of the pressure (the bar
    starts at rest; class (c) of tests/roundoff.py)."""
    runs = {}
    probes = (("s", (0.01, 0.3), "sigma_zz"), ("ep", (0.01, 0.2), "eps_p_eq"),
              ("vm", (0.01, 0.45), "von_mises"))
    cases = (("world", MPI.COMM_WORLD, 600e6), ("self", MPI.COMM_SELF, 600e6))
    if MPI.COMM_WORLD.size > 1:
        cases += (("ulp", MPI.COMM_SELF, one_ulp(600e6)),)
    for name, comm, P in cases:
        sim, _ = _wave(0.01, comm=comm, P=P, L=0.6, t_end=8e-5, probes=probes)
        sim.run()
        f = sim.integrator.nonlinear[0]
        total_ep = comm.allreduce(float((f.geometry.w * f.qs.state[..., 0]).sum()))
        runs[name] = (sim.history.data(), sim.energy.data(), total_ep, sim.n_steps)
    (hw, ew, pw, n), (hs, es, ps, _) = runs["world"], runs["self"]
    hu, eu, pu, _ = runs.get("ulp", (None, None, None, None))
    for col in ("s", "ep", "vm"):
        assert_runs_agree(hw[col], hs[col], None if hu is None else hu[col], n, col)
    scale = np.abs(es["total"]).max()
    for col in ("kinetic", "strain", "plastic_work", "deformation_work", "external_work"):
        assert_runs_agree(ew[col], es[col], None if eu is None else eu[col], n, col, scale)
    assert_runs_agree(pw, ps, pu, n, "total eps_p")
    assert ps > 0


def test_generic_path_same_on_all_partitions():
    """The generic (dolfinx) path on all ranks gives the fast path's serial histories: other
    expressions (and partitions) at every step, so within the steps x the spread of the
    fast serial run under a one-ulp change of the pressure (class (c))."""
    hist = {}
    for name, comm, p, P in (("world", MPI.COMM_WORLD, "generic", 600e6),
                             ("self", MPI.COMM_SELF, "fast", 600e6),
                             ("ulp", MPI.COMM_SELF, "fast", one_ulp(600e6))):
        mat = J2(E=200e9, nu=0.3, density=7850.0, yield_stress=200e6, hardening=10e9)
        tm = meshing.bar(radius=0.02, length=0.6, h=0.01, structured=True, comm=comm)
        model = DeformableModel(tm, [Body("bar", mat)])
        sim = Simulation(model, Settings(cfl=0.5, t_end=8e-5, output_every=50, quiet=True,
                                         fields=False, f_int_path=p),
                         fixed=[model.body_dofs("bar", 0)],
                         loads=[loads.SurfaceLoad(model, "loaded_end", loads.Constant(P))])
        sim.add_probe("s", (0.01, 0.3), "sigma_zz")
        sim.run()
        hist[name] = sim.history.data()["s"]
    assert_within_spread(hist["world"], hist["self"], hist["ulp"], sim.n_steps, "s")


def test_mixed_plastic_impact_ledger_and_outputs(tmp_path):
    """A linear striker at 50 m/s on a J2 target that yields, DME contact, fields written:
    the ledger (kinetic + stored elastic + plastic work vs contact work, DME jumps booked)
    closes to round-off, the target dissipates, and the plastic cell fields are in the
    XDMF output and the probes (yielded = 0 in the linear striker)."""
    comm = MPI.COMM_WORLD
    out = comm.bcast(str(tmp_path / "mixed") if comm.rank == 0 else None, root=0)
    tm = meshing.coaxial_bars(radius=0.05, striker_length=0.2, target_length=0.25, h=0.025)
    model = DeformableModel(tm, [Body("striker", STEEL),
                                 Body("target", J2(yield_stress=100e6, hardening=1e9))])
    sim = Simulation(model, Settings(dt=1e-6, n_steps=200, output_every=20, quiet=True, out=out,
                                     plots=False),
                     initial_velocity={"striker": (0.0, 50.0)})
    sim.add_contact(pair_surfaces(model, "striker_contact", "target_contact"),
                    scenes.make_method("dme"))
    sim.add_probe("ep", (0.01, 0.01), "eps_p_eq")
    sim.add_probe("y_target", (0.01, 0.01), "yielded")
    sim.add_probe("y_striker", (0.01, -0.01), "yielded")
    s = sim.run()
    assert s["energy_balance_error_rel"] <= ledger(200, s["n_dofs"])
    assert s["plastic_dissipation"] > 0.01 * s["energy"]["total"]
    h = sim.history.data()
    assert h["ep"][-1] > 0 and h["y_target"][-1] == 1.0 and h["y_striker"][-1] == 0.0
    cells = sim.cell_fields()  # for a field writer: per owned cell
    n_owned = model.mesh.topology.index_map(2).size_local
    assert all(v.shape == (n_owned,) for v in cells.values())
    striker = model.tmesh.cells("striker")
    assert not cells["yielded"][striker[striker < n_owned]].any()
    assert comm.allreduce(int(cells["yielded"].sum())) > 0
    if comm.rank == 0:
        with open(f"{out}/fields.xdmf") as f:
            text = f.read()
        assert 'Name="eps_p_eq"' in text and 'Name="yielded"' in text


def test_kinetic_identity_with_the_plastic_internal_force():
    """1/2 v'Mv changes by exactly 1/2 dt (v^n + v^{n+1}) . f^n each step, f^n every force in
    the velocity update: here -f_int(u^n) of a yielding J2 bar (as the quadrature force
    reports it) plus the pressure on its end. Summed over 2000 steps, to the round-off of
    a ledger (roundoff.ledger: the dot product here, summed by BLAS in blocks, rounds
    about log2(n_dofs) times a step, within its count)."""
    mat = J2(E=200e9, nu=0.3, density=7850.0, yield_stress=200e6, hardening=5e9)
    tm = meshing.bar(radius=0.02, length=0.1, h=0.01, structured=True)
    model = DeformableModel(tm, [Body("bar", mat)])
    load = loads.SurfaceLoad(model, "loaded_end", loads.Trapezoid(700e6, 2e-5, 4e-4, 6e-4))
    sim = Simulation(model, Settings(cfl=0.5, n_steps=1, quiet=True, fields=False),
                     fixed=[model.facet_dofs("free_end", 1)], loads=[load])
    integ, comm = sim.integrator, sim.comm
    force = integ.nonlinear[0]
    m, dt = integ.mass, integ.dt
    free = np.ones(model.n_owned, dtype=bool)
    free[integ.fixed] = False
    f_ext = np.zeros(model.n_owned)
    work = kinetic0 = 0.0
    v_now = np.empty(model.n_owned)
    for n in range(2000):
        integ.velocity(v_now)
        f_ext[:] = 0.0
        f_ext[load.dofs] = load.force * load.history(integ.t)
        integ.predict()
        integ.advance()
        f = np.where(free, f_ext - force.f_owned, 0.0)  # fixed dofs: no force acts
        work += 0.5 * dt * float(np.dot(v_now + integ.v_owned, f))
    kinetic = 0.5 * float(np.dot(m * integ.v_owned, integ.v_owned))
    work, kinetic = comm.allreduce(work), comm.allreduce(kinetic)
    n_dofs = comm.allreduce(model.n_owned)
    assert abs(kinetic - kinetic0 - work) <= ledger(2000, n_dofs) * max(abs(kinetic), abs(work))
    assert comm.allreduce(force.plastic_work_local) > 0.1 * kinetic > 0


# ---------------------------------------------------------------- output stresses
EPS = np.finfo(float).eps


def _impact(target, out=None, n_steps=200, probes=()):
    """A linear striker at 50 m/s on ``target`` (DME), fields every 20 steps; the frames'
    (step, stresses (5, owned cells), eps_bar_p at the target's points) captured as the
    loop writes them (Python steps: compiled blocks of linear bodies write their own)."""
    tm = meshing.coaxial_bars(radius=0.05, striker_length=0.2, target_length=0.25, h=0.025)
    model = DeformableModel(tm, [Body("striker", STEEL), Body("target", target)])
    sim = Simulation(model, Settings(dt=1e-6, n_steps=n_steps, output_every=20, quiet=True,
                                     out=out, plots=False, compiled_steps=False),
                     initial_velocity={"striker": (0.0, 50.0)})
    sim.add_contact(pair_surfaces(model, "striker_contact", "target_contact"),
                    scenes.make_method("dme"))
    for name, point, quantity in probes:
        sim.add_probe(name, point, quantity)
    frames = []
    write = sim._write_fields

    def capture(writer):
        write(writer)
        force = sim.integrator.nonlinear[0] if sim.integrator.nonlinear else None
        frames.append((sim.integrator.n, sim._stress_block.copy(),
                       None if force is None else force.frame.state[..., 0].copy()))
    sim._write_fields = capture
    sim.run()
    return sim, frames


def test_output_stresses_satisfy_the_yield_condition(tmp_path):
    """J2 target (rate-independent, linear hardening) that yields under a 50 m/s impact: in
    every frame every target cell's von Mises is at most the largest current yield stress
    of its points, sigma_y0 + H max_q eps_bar_p,q (the mean of stresses inside a convex
    surface is inside it). Bound: 32 eps x the cell's largest stress component, the
    round-off of the ~30 rounded operations from the strain through the return, the
    weighted mean and the von Mises of the mean (the pressure, larger than sigma_y here,
    is lost in the deviator to eps of its size). The probes in a yielded cell equal the
    frame's value of that cell exactly (the same kernel on the same numbers)."""
    comm = MPI.COMM_WORLD
    out = _out(tmp_path, "yield")
    sy0, H = 100e6, 1e9
    probes = [("vm", (0.01, 0.01), "von_mises"), ("szz", (0.01, 0.01), "sigma_zz"),
              ("ep", (0.01, 0.01), "eps_p_eq")]
    sim, frames = _impact(J2(yield_stress=sy0, hardening=H), out, probes=probes)
    force = sim.integrator.nonlinear[0]
    cells = force.cells
    worst, yielded, checked = -np.inf, 0, 0
    for _, block, eps_bar in frames:
        sy = sy0 + H * eps_bar.max(axis=1)
        scale = np.abs(block[:4, cells]).max(axis=0)
        excess = block[4, cells] - sy - 32 * EPS * scale
        worst = max(worst, float(excess.max(initial=-np.inf)))
        yielded = max(yielded, comm.allreduce(int((eps_bar.max(axis=1) > 0).sum())))
        checked += comm.allreduce(cells.size)
    assert comm.allreduce(worst, op=MPI.MAX) <= 0.0
    n_target = comm.allreduce(cells.size)
    assert yielded > n_target // 4 and checked == len(frames) * n_target  # a scene that yields
    # the probes' cell: the history row of each frame's step holds the frame's value
    from impact_fenics.probes import locate_cell

    h = sim.history.data()
    cell, mine = locate_cell(sim.model.mesh, (0.01, 0.01))
    mismatch = 0
    for n, block, eps_bar in frames[1:]:
        row = np.flatnonzero(h["step"] == n)
        assert row.size == 1
        if mine:
            mismatch += h["vm"][row[0]] != block[4, cell]
            mismatch += h["szz"][row[0]] != block[1, cell]
            mismatch += h["ep"][row[0]] != eps_bar[np.searchsorted(cells, cell)].mean()
    assert comm.allreduce(mismatch) == 0
    assert comm.allreduce(int(mine)) == 1 and h["ep"][-1] > 0


def _out(tmp_path, name):
    comm = MPI.COMM_WORLD
    return comm.bcast(str(tmp_path / name) if comm.rank == 0 else None, root=0)


def test_linear_body_beside_a_plastic_one_outputs_the_linear_kernel(tmp_path):
    """The striker's cells of a frame of the mixed run (J2 target that yields) are exactly
    what the cell stresses of an all-linear model give for the same displacement: the
    same expression (lambda tr eps + 2 mu eps at the centroid) on the same numbers."""
    from impact_fenics.cell_fields import CellStress

    from dolfinx import fem

    sim, frames = _impact(J2(yield_stress=100e6, hardening=1e9), _out(tmp_path, "mixed"),
                          n_steps=60)
    model = sim.model
    linear = DeformableModel(model.tmesh, [Body("striker", STEEL), Body("target", STEEL)])

    u = fem.Function(linear.V)
    u.x.array[: model.n_owned] = sim.integrator.u_owned
    u.x.scatter_forward()
    values = CellStress(linear).evaluate(u.x.array)
    n_owned = model.mesh.topology.index_map(2).size_local
    striker = model.tmesh.cells("striker")
    striker = striker[striker < n_owned]
    _, last, _ = frames[-1]
    assert frames[-1][0] == sim.integrator.n  # the last frame is the final state
    assert np.array_equal(last[:, striker], values[:, striker])
    assert MPI.COMM_WORLD.allreduce(striker.size) > 0


def test_never_yielding_j2_frames_are_the_linear_frames(tmp_path):
    """A J2 target that never yields against the linear target, frame by frame: the weighted
    mean of its point stresses against D eps at the centroid, equal in exact arithmetic
    (cell_fields' module note). Bound per cell: 32 eps x (3 lambda + 2 mu) x |u| x the
    largest of |grad N| and 1/r at its points: the strains of both paths are sums of
    nodal displacements (up to the striker's travel, far above the strain x h) times
    those factors, each rounded a few times, and the mean adds a few roundings."""
    mat = J2(E=STEEL.E, nu=STEEL.nu, density=STEEL.density, yield_stress=NEVER)
    _, ref = _impact(STEEL, _out(tmp_path, "linear"), n_steps=100)
    sim, got = _impact(mat, _out(tmp_path, "j2"), n_steps=100)
    force = sim.integrator.nonlinear[0]
    g, cells = force.geometry, force.cells
    u = sim.integrator.u_owned
    # the largest |u| of each target cell's nodes (owned; a ghost node's u is its owner's,
    # bounded by the body's largest |u| on any rank, taken instead)
    u_max = MPI.COMM_WORLD.allreduce(float(np.abs(u).max()), op=MPI.MAX)
    factor = np.max(np.concatenate([np.abs(g.dNdr), np.abs(g.dNdz), g.inv_r], axis=1), axis=1)
    bound = 32 * EPS * (3 * mat.lmbda + 2 * mat.mu) * u_max * factor
    assert len(ref) == len(got) == 6
    bad = 0
    for (n_ref, a, _), (n, b, _) in zip(ref, got):
        assert n == n_ref
        bad += int((np.abs(a[:, cells] - b[:, cells]) > bound).sum())
    assert MPI.COMM_WORLD.allreduce(bad) == 0
