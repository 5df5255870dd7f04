"""demos/custom_plastic_material.py: a user's point update runs through the ordinary API.

Oracles: with no hardening the Voce material is the package's J2 with H = 0 (the
same run by another point update: the histories within the steps x the spread of
the J2 run under a one-ulp change of the pressure, tests/roundoff.py); in uniaxial
strain the elastic precursor is sigma_HEL = sigma_0 (1 - nu)/(1 - 2 nu) within the
dispersion bound (h / c_L t)^(2/3) of the scheme (see test_plasticity's wave test);
the ledger with plastic dissipation closes to the round-off of a ledger. At finite
strain, without hardening the Voce material is the package's FiniteJ2 with H = 0 (within
the spread of a one-ulp change of the impact speed); the demo's scene file, which names
the class by its import path, is checked in tests/test_material_names.py.
"""
from conftest import load_demo
from impact_fenics.materials.j2 import J2
from roundoff import assert_within_spread, ledger, one_ulp

demo = load_demo("custom_plastic_material")


def test_voce_without_hardening_is_j2():
    h, t_end = 0.02, 6e-5
    voce = demo.run(demo.VoceJ2(sigma_0=200e6, sigma_inf=200e6, delta=0.0, **demo.STEEL), h=h,
                    t_end=t_end)
    j2 = demo.run(J2(yield_stress=200e6, hardening=0.0, **demo.STEEL), h=h, t_end=t_end)
    pressure = demo.P
    try:
        demo.P = one_ulp(pressure)
        ulp = demo.run(J2(yield_stress=200e6, hardening=0.0, **demo.STEEL), h=h, t_end=t_end)
    finally:
        demo.P = pressure
    a, b, u = voce.history.data(), j2.history.data(), ulp.history.data()
    for col in (c for c in a if c.startswith(("sigma", "eps_p"))):
        assert_within_spread(a[col], b[col], u[col], j2.n_steps, col)


def test_voce_precursor_and_ledger():
    h = 0.01
    sim = demo.run(demo.VoceJ2(sigma_0=200e6, sigma_inf=400e6, delta=50.0, **demo.STEEL), h=h)
    c = demo.precursor_check(sim, h)
    assert c["error_rel"] <= c["bound"]
    assert c["energy_balance_error_rel"] <= ledger(sim.n_steps, sim.model.n_global)
    assert 0.0 < c["plastic_dissipation"] < c["external_work"]


def test_finite_voce_without_hardening_is_finite_j2():
    """At finite strain, the Voce material with sigma_inf = sigma_0 on the demo's short Taylor
    bar is FiniteJ2 with H = 0 (the same return by another Newton loop): the summary within
    the steps x the spread of the FiniteJ2 run under a one-ulp change of v0."""
    from impact_fenics.materials import FiniteJ2

    voce = demo.taylor(demo.FiniteVoceJ2(sigma_0=400e6, sigma_inf=400e6, delta=0.0, **demo.COPPER))
    j2 = demo.taylor(FiniteJ2(yield_stress=400e6, hardening=0.0, **demo.COPPER))
    ulp = demo.taylor(FiniteJ2(yield_stress=400e6, hardening=0.0, **demo.COPPER),
                      v0=one_ulp(demo.V_BAR))
    assert voce["n_steps"] == j2["n_steps"] and voce["eps_p_max"] > 0.5
    for key in demo.FINITE_KEYS:
        assert_within_spread(voce[key], j2[key], ulp[key], j2["n_steps"], key)
