"""The split Hopkinson bar's wave analysis (impact_fenics.shpb.waves) on waves made by the
1D theory of the test, so the answer is known: a specimen of a smooth law
sigma(eps) = sigma_y tanh(E_s eps / sigma_y) + H eps, strained at a rate that rises smoothly
to 2000 1/s, in equilibrium. At the faces the waves are then (compression positive)

    eps_R = -rate L_s / (2 c0),   eps_T = sigma(eps) A_s / (E A_b),   eps_I = eps_T - eps_R,

and the gauges record them shifted by their distances over c0. The analysis must give back
the rate, the strain and the law.

* Gauges at a whole number of samples from the faces: every wave is read at a sample
  (no interpolation), the rate is piecewise smooth and the strain its trapezoid integral:
  the 1- and 3-wave stresses against the law at the 1- and 3-wave strains to the trapezoid
  rule's error, bounded by T dt^2 max|rate''| / 12 times the law's largest slope, plus
  round-off;
* gauges at fractions of a sample: each wave by linear interpolation, within
  dt^2 / 8 max|f''| of the exact wave (f'' from the closed forms);
* in equilibrium the 1- and 3-wave rates agree and the ratio R is zero, to round-off;
  out of equilibrium R is 2 |F_front - F_back| / (F_front + F_back) by hand;
* a pulse longer than the incident gauge's window, or a record too short, is refused.

Pure numpy: the same on every rank.
"""
import math

import numpy as np
import pytest

from impact_fenics.errors import InputError
from impact_fenics.shpb.waves import Bars, Gauges, Specimen, analyse, separate
from roundoff import rounding

BARS = Bars(E=200e9, density=7850.0, area=math.pi * 0.01 ** 2)
SPECIMEN = Specimen(length=5e-3, area=math.pi * 0.005 ** 2)
E_S, SIGMA_Y, H = 100e9, 300e6, 1e9   # the specimen's law (Pa)
RATE, RISE = 2000.0, 10e-6            # plateau strain rate (1/s), its smooth rise (s)
PULSE = 100e-6                        # s
DT = 1e-7                             # s, the records' sampling


def _rate(tau):
    tau = np.asarray(tau, dtype=float)
    rising = 0.5 * RATE * (1.0 - np.cos(math.pi * tau / RISE))
    return np.where(tau < RISE, rising, RATE) * ((tau >= 0.0) & (tau <= PULSE))


def _strain(tau):
    tau = np.clip(np.asarray(tau, dtype=float), 0.0, PULSE)
    rising = 0.5 * RATE * (tau - RISE / math.pi * np.sin(math.pi * tau / RISE))
    return np.where(tau < RISE, rising, 0.5 * RATE * RISE + RATE * (tau - RISE))


def _law(eps):
    return SIGMA_Y * np.tanh(E_S * eps / SIGMA_Y) + H * eps


def _face_waves(tau):
    """(incident, reflected, transmitted) at the faces at times tau after the incident
    wave's arrival there (0 outside the pulse)."""
    inside = (tau >= 0.0) & (tau <= PULSE)
    reflected = -_rate(tau) * SPECIMEN.length / (2.0 * BARS.c0)
    transmitted = np.where(inside, _law(_strain(tau)) * SPECIMEN.area / (BARS.E * BARS.area), 0.0)
    return transmitted - reflected, reflected, transmitted


def _records(d_i, d_t, arrival, t_end=600e-6):
    t = DT * np.arange(int(round(t_end / DT)) + 1)
    c0 = BARS.c0
    inc, _, _ = _face_waves(t - arrival)
    _, ref, _ = _face_waves(t - arrival - 2.0 * d_i / c0)
    _, _, tra = _face_waves(t - arrival - (d_i + d_t) / c0)
    return t, inc + ref, tra


def _run(samples_i, samples_t, arrival_samples=500):
    c0 = BARS.c0
    d_i, d_t = samples_i * DT * c0, samples_t * DT * c0
    gauges = Gauges(incident=d_i, transmitter=d_t, arrival=arrival_samples * DT)
    t, gi, gt = _records(d_i, d_t, gauges.arrival)
    waves = separate(t, gi, gt, BARS, gauges, PULSE)
    return waves, analyse(waves, BARS, SPECIMEN)


def _second_derivative_bound(f, tau):
    """max |f''| over tau from second differences on a grid 100 times finer than the
    records' (the closed forms are smooth between their few kinks, where the bound is
    taken from the jump of f' instead: see the callers)."""
    h = DT / 100.0
    fine = np.arange(tau[0], tau[-1], h)
    return float(np.max(np.abs(np.diff(f(fine), 2)))) / h ** 2


def test_the_law_comes_back_at_whole_samples():
    waves, a = _run(samples_i=2000, samples_t=1500)
    tau = waves.t - waves.t[0]
    inc, ref, tra = _face_waves(tau)
    scale = float(np.max(np.abs(inc)))
    # a sample read at its own time: the face time start + k dt and the record's k' dt
    # differ by a few roundings of t (<= 600 us), and the records' slope is at most a
    # wave's jump over one sample (at the pulse's ends), scale / DT
    wave_err = rounding(8, 600e-6) * scale / DT + rounding(64, scale)
    for got, want in ((waves.incident, inc), (waves.reflected, ref), (waves.transmitted, tra)):
        assert np.max(np.abs(got - want)) <= wave_err
    c0_l = BARS.c0 / SPECIMEN.length
    rate_err = 3.0 * c0_l * wave_err + rounding(16, RATE)   # a rate is three waves' sum
    stress_err = 3.0 * BARS.E * BARS.area / SPECIMEN.area * wave_err + rounding(16, SIGMA_Y)
    # the trapezoid rule on the rate: T dt^2 max|rate''| / 12 (rate'' = RATE (pi/RISE)^2 / 2
    # on the rise), the rates' errors over the pulse, the summed roundings of N terms
    n = waves.t.size
    trapezoid = PULSE * DT ** 2 * RATE * (math.pi / RISE) ** 2 / 2.0 / 12.0
    strain_err = trapezoid + PULSE * rate_err + rounding(4 * n, float(_strain(PULSE)))
    for strain, stress in ((a.strain_1, a.stress_1), (a.strain_3, a.stress_3)):
        assert np.max(np.abs(strain - _strain(tau))) <= strain_err
        # sigma at the recovered strain: the law's slope at most E_S + H
        assert np.max(np.abs(stress - _law(strain))) <= (E_S + H) * strain_err + stress_err
    # in equilibrium: the 3-wave rate is the 1-wave's, the three stresses agree, and R is
    # zero up to the forces' errors over the force
    assert np.max(np.abs(a.rate_3 - a.rate_1)) <= rate_err
    for stress in (a.stress_2, a.stress_3):
        assert np.max(np.abs(stress - a.stress_1)) <= stress_err
    loaded = a.force_back > 0.01 * np.max(a.force_back)
    force_err = stress_err * SPECIMEN.area
    assert np.max(a.equilibrium[loaded]) <= 4.0 * force_err / np.min(a.force_back[loaded])
    # the plateau: equilibrium everywhere, the rate within 10 % of 2000 after the rise
    mask = a.plateau()
    assert mask.sum() > 0.8 * mask.size
    assert np.all(np.abs(a.rate_3[mask] - RATE) <= 0.1 * RATE)
    # true values: constant volume
    eps = a.strain_3[-1]
    assert a.true_strain(a.strain_3)[-1] == pytest.approx(-math.log(1.0 - eps), rel=rounding(4))
    cols = a.columns()
    assert set(cols) >= {"time", "stress_1", "stress_2", "stress_3", "true_stress_3",
                         "equilibrium_ratio", "strain_rate_1", "strain_rate_3"}
    assert all(v.shape == a.t.shape for v in cols.values())


def test_fractional_gauge_positions_interpolate_within_their_bound():
    waves, _ = _run(samples_i=2000.37, samples_t=1500.71)
    tau = waves.t - waves.t[0]
    for k, got in enumerate((waves.incident, waves.reflected, waves.transmitted)):
        def exact(x, k=k):
            return _face_waves(x)[k]
        # linear interpolation between samples errs by at most dt^2 / 8 max|f''| where f is
        # smooth; the waves' kinks (the pulse's ends, where f jumps or f' jumps) are
        # excluded: one sample either side of 0 and PULSE
        smooth = (tau > 2 * DT) & (tau < PULSE - 2 * DT)
        bound = DT ** 2 / 8.0 * _second_derivative_bound(exact, (2 * DT, PULSE - 2 * DT))
        scale = float(np.max(np.abs(exact(tau))))
        assert np.max(np.abs(got - exact(tau))[smooth]) <= 1.01 * bound + rounding(64, scale)


def test_out_of_equilibrium_ratio_by_hand():
    waves, _ = _run(samples_i=2000, samples_t=1500)
    waves.incident = waves.incident * 1.1  # the front face pushed 10 % of eps_I harder
    a = analyse(waves, BARS, SPECIMEN)
    k = int(np.argmax(a.force_back))
    stiffness = BARS.E * BARS.area
    front = stiffness * (waves.incident[k] + waves.reflected[k])
    back = stiffness * waves.transmitted[k]
    assert a.equilibrium[k] == pytest.approx(2.0 * abs(front - back) / (front + back),
                                             rel=rounding(16))
    assert a.equilibrium[k] > 0.05


def test_overlapping_or_short_records_are_refused():
    c0 = BARS.c0
    t, gi, gt = _records(0.1, 0.1, 1e-4)
    with pytest.raises(InputError, match="overlap at the gauge"):
        separate(t, gi, gt, BARS, Gauges(0.2, 0.2, 1e-4), 2.0 * 0.2 / c0 + 1e-6)
    with pytest.raises(InputError, match="run longer"):
        separate(t[:3000], gi[:3000], gt[:3000], BARS, Gauges(0.4, 0.4, 1e-4), PULSE)
    with pytest.raises(InputError, match="away from the specimen"):
        separate(t, gi, gt, BARS, Gauges(0.0, 0.2, 1e-4), PULSE)


def test_the_dispersion_correction_brings_back_the_face_waves():
    """Smooth face waves (60 us plateaus with 5 us Gaussian edges; a 10 mm steel bar,
    nu = 0.29) recorded at gauges 1.5 m and 1 m away through the bars' first mode: each
    gauge record is its face wave moved over the gauge's distance by the dispersion
    (dispersion.correct: towards the face for the incident wave, away from it for the
    others) and delayed by d/c0, at whole samples. separate() with the correction gives
    the face waves back. The bound: the correction is unitary on the padded record and the
    windows and the whole-sample reading do not enlarge the 2-norm, so a wave is off by at
    most what the windows move to the other wave (the incident record's part after the
    switch, the reflected record's part before it), plus the round-off of two moves
    (test_shpb_dispersion.fft_roundoff each, on the record's 2-norm). Without the
    correction the waves are off by the dispersion itself (over 1 % of the peak)."""
    from impact_fenics.shpb import dispersion
    from impact_fenics.shpb.waves import Dispersion
    from test_shpb_dispersion import NU_STEEL, fft_roundoff, gaussian

    radius, dt = 0.01, 0.2e-6
    bars = Bars(E=200e9, density=7850.0, area=math.pi * radius ** 2)
    c0 = bars.c0
    d_i, d_t = 7_500 * dt * c0, 5_000 * dt * c0  # 1.51 m, 1.01 m: whole samples
    lag = d_i / c0 * (1.0 / dispersion.slowest_group_velocity(NU_STEEL) - 1.0)
    arrival = dt * math.ceil((2_000 * dt + lag) / dt)  # room for the incident record's lead
    sigma, plateau = 5e-6, 60e-6
    pulse = plateau + 10 * sigma

    def bump(tau):  # a smooth pulse over [0, pulse]
        start, end = 5 * sigma, 5 * sigma + plateau
        return np.where(tau < start, gaussian(tau, start, sigma),
                        np.where(tau > end, gaussian(tau, end, sigma), 1.0))

    t = dt * np.arange(int((arrival + 2 * d_i / c0 + pulse + 2 * lag + d_t / c0) / dt))
    amplitudes = (1e-3, -6e-4, 4e-4)  # incident, reflected, transmitted at the faces

    def at_gauge(k, delay, distance):
        return dispersion.correct(t, amplitudes[k] * bump(t - delay), distance, radius,
                                  NU_STEEL, c0)

    incident = at_gauge(0, arrival, -d_i)
    reflected = at_gauge(1, arrival + 2 * d_i / c0, d_i)
    transmitted = at_gauge(2, arrival + (d_i + d_t) / c0, d_t)
    gauges = Gauges(incident=d_i, transmitter=d_t, arrival=arrival)
    got = separate(t, incident + reflected, transmitted, bars, gauges, pulse,
                   Dispersion(radius=radius, nu=NU_STEEL))
    plain = separate(t, incident + reflected, transmitted, bars, gauges, pulse)
    switch = arrival + 2 * d_i / c0
    crossed = (np.linalg.norm(incident[t >= switch]) + np.linalg.norm(reflected[t < switch]))
    tau = got.t - got.t[0]
    for k, (wave, raw, record) in enumerate(((got.incident, plain.incident, incident),
                                             (got.reflected, plain.reflected, reflected),
                                             (got.transmitted, plain.transmitted, transmitted))):
        exact = amplitudes[k] * bump(tau)
        distance = d_t if k == 2 else d_i
        bound = (crossed if k < 2 else 0.0) + 2.0 * fft_roundoff(t, distance) * float(
            np.linalg.norm(record))
        error = float(np.max(np.abs(wave - exact)))
        off = float(np.max(np.abs(raw - exact)))
        print(f"wave {k}: corrected within {error:.2e}, uncorrected off by {off:.2e} "
              f"(peak {abs(amplitudes[k]):.1e}, bound {bound:.2e})")
        assert error <= bound
        assert off > 0.01 * abs(amplitudes[k])
    assert got.cut == () and plain.cut == ()  # the records end at rest
    assert crossed <= 0.02 * amplitudes[0]  # the windows cut little: the bound says something


def test_a_record_cut_before_the_reflected_wave_has_passed_is_named():
    """A reflected wave longer than the analysed pulse (a shaped pulse's tail), recorded
    through the first mode's dispersion at a gauge 0.35 m from the face, and a record that
    ends 5 us after the reflected window, while the gauge still reads the whole wave: the
    zero padding makes a step there, and the backward move carries its short waves up to
    d (1/c_g,min - 1/c0) = 115 us ahead of it, into the window. separate() with the
    correction names the reflected wave in Waves.cut, and the wave is indeed off (by over
    10 % of its peak); the same record run on until the wave has passed, the slowest
    group's lag beyond the window, gives it back within the bound of the test above (what
    the windows move between the waves at the switch, plus round-off) and names nothing."""
    from impact_fenics.shpb import dispersion
    from impact_fenics.shpb.waves import Dispersion
    from test_shpb_dispersion import NU_STEEL, fft_roundoff, gaussian

    radius, dt = 0.01, 0.2e-6
    bars = Bars(E=200e9, density=7850.0, area=math.pi * radius ** 2)
    c0 = bars.c0
    d_i, d_t = 350 * dt * c0, 50 * dt * c0  # 0.35 m, 0.05 m: whole samples
    lag = d_i / c0 * (1.0 / dispersion.slowest_group_velocity(NU_STEEL) - 1.0)
    arrival = dt * math.ceil((2_000 * dt + lag) / dt)
    sigma, plateau = 5e-6, 60e-6
    pulse = plateau + 10 * sigma

    def bump(tau, longer=0.0):  # a smooth pulse over [0, pulse + longer]
        start, end = 5 * sigma, 5 * sigma + plateau + longer
        return np.where(tau < start, gaussian(tau, start, sigma),
                        np.where(tau > end, gaussian(tau, end, sigma), 1.0))

    window_end = arrival + 2 * d_i / c0 + pulse  # the reflected window's end at the gauge
    tail = 100e-6  # the reflected wave lasts this much longer than the analysed pulse
    t = dt * np.arange(int((window_end + tail + 10 * sigma + 2 * lag) / dt))

    def at_gauge(amplitude, delay, distance, longer=0.0):
        return dispersion.correct(t, amplitude * bump(t - delay, longer), distance, radius,
                                  NU_STEEL, c0)

    incident = at_gauge(1e-3, arrival, -d_i)
    reflected = at_gauge(-6e-4, arrival + 2 * d_i / c0, d_i, tail)
    gauge_i = incident + reflected
    gauge_t = at_gauge(4e-4, arrival + (d_i + d_t) / c0, d_t)
    gauges = Gauges(incident=d_i, transmitter=d_t, arrival=arrival)
    disp = Dispersion(radius=radius, nu=NU_STEEL)
    whole = separate(t, gauge_i, gauge_t, bars, gauges, pulse, disp)
    n = int(round((window_end + 5e-6) / dt))
    cut = separate(t[:n], gauge_i[:n], gauge_t[:n], bars, gauges, pulse, disp)
    exact = -6e-4 * bump(whole.t - whole.t[0], tail)
    off_whole = float(np.max(np.abs(whole.reflected - exact))) / 6e-4
    off_cut = float(np.max(np.abs(cut.reflected - exact))) / 6e-4
    print(f"reflected off by {off_whole:.1e} (whole record), {off_cut:.1e} (cut) of its peak")
    # the bound of the test above: what the windows move to the other wave, plus two moves'
    # round-off on the record's 2-norm
    switch = arrival + 2 * d_i / c0
    crossed = np.linalg.norm(incident[t >= switch]) + np.linalg.norm(reflected[t < switch])
    bound = crossed + 2.0 * fft_roundoff(t, d_i) * float(np.linalg.norm(reflected))
    print(f"bound on the whole record {bound / 6e-4:.1e} of the peak")
    assert whole.cut == ()
    assert off_whole * 6e-4 <= bound
    assert cut.cut == ("reflected",)
    assert off_cut > 0.1


def test_the_command_warns_of_a_cut_record_in_one_line():
    """impact-fenics shpb --dispersion's warning: one line naming the cut wave; none
    without a cut."""
    from impact_fenics.shpb.run_analysis import cut_warning
    from impact_fenics.shpb.waves import Waves

    t = np.zeros(3)
    line = cut_warning(Waves(t, t, t, t, cut=("reflected",)))
    assert line.startswith("warning: ") and "reflected wave" in line and "\n" not in line
    assert cut_warning(Waves(t, t, t, t)) is None


def test_the_plateau_is_the_loadings_rate_not_the_unloadings():
    """A window that holds a whole pulse (a shaped one: loading, then unloading): the rate
    rises to 2000 1/s over 100 samples, holds 400 and falls to 0 over the last 500, in
    equilibrium throughout. The plateau is the 400 held samples (and the ramps' samples
    within 10 % of 2000), by hand; the median of every sample would be about 1600 1/s
    and miss them."""
    from impact_fenics.shpb.waves import Analysis

    rate = np.concatenate([np.linspace(0.0, RATE, 100, endpoint=False), np.full(400, RATE),
                           np.linspace(RATE, 0.0, 500)])
    n = rate.size
    zero = np.zeros(n)
    a = Analysis(t=np.arange(n) * 1e-8, force_front=zero, force_back=zero, equilibrium=zero,
                 rate_1=rate, rate_3=rate, strain_1=zero, strain_3=zero, stress_1=zero,
                 stress_2=zero, stress_3=zero)
    assert abs(float(np.median(rate)) - RATE) > 0.1 * RATE  # what the whole window's median misses
    assert np.array_equal(a.plateau(), np.abs(rate - RATE) <= 0.1 * RATE)
    assert a.plateau().sum() >= 400
