"""demos/custom_plastic_material.py: a user's point update runs through the ordinary API.

Oracles: with no hardening the Voce material is the package's J2 with H = 0 (the
same run, histories equal to round-off); in uniaxial strain the elastic
precursor is sigma_HEL = sigma_0 (1 - nu)/(1 - 2 nu) within the dispersion
bound (h / c_L t)^(2/3) of the scheme (see test_plasticity's wave test); the
ledger with plastic dissipation closes to round-off.
"""
from conftest import load_demo

demo = load_demo("custom_plastic_material")


def test_voce_without_hardening_is_j2():
    assert demo.reduction_check(h=0.02) <= 1e-12


def test_voce_precursor_and_ledger():
    h = 0.01
    sim = demo.run(demo.VoceJ2(sigma_0=200e6, sigma_inf=400e6, delta=50.0, **demo.STEEL), h=h)
    c = demo.precursor_check(sim, h)
    assert c["error_rel"] <= c["bound"]
    assert c["energy_balance_error_rel"] <= 1e-12
    assert 0.0 < c["plastic_dissipation"] < c["external_work"]
