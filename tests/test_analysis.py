"""Analysis functions on synthetic data with known answers."""

import math
import warnings

import numpy as np
import pytest
from conftest import slow_noise

from silo_dolfinx import analysis, theory


def test_spectrum_finds_5_hz_and_0_7_hz_within_one_bin():
    rate, T = 200.0, 60.0  # the ch. 4 discharge: 60 s at 200 Hz
    t = np.arange(0.0, T, 1.0 / rate)
    x = 1000.0 + 30.0 * t + 400.0 * np.sin(2 * math.pi * 0.7 * t) + 100.0 * np.sin(2 * math.pi * 5.0 * t + 0.3)
    sp = analysis.spectrum(t, x)
    assert abs(sp.resolution - 1 / T) < 1e-3 / T
    peaks = sp.peaks(2, min_frequency=0.1)
    assert abs(peaks[0] - 0.7) < sp.resolution and abs(peaks[1] - 5.0) < sp.resolution
    # amplitudes are window-corrected (a Hann window loses 50 % coherent gain otherwise)
    i = np.argmin(abs(sp.frequency - 5.0))
    assert abs(sp.amplitude[i] - 100.0) < 3.0


def test_time_average_eq_4_9():
    t = np.linspace(0, 10, 1001)
    p = 3.0 + np.sin(2 * math.pi * t)
    assert abs(analysis.time_average(t, p, 2.0, 6.0) - 3.0) < 1e-2
    with pytest.raises(ValueError):
        analysis.time_average(t, p, 20.0, 30.0)


def test_representative_deviation_eqs_3_13_and_5_18():
    p0 = np.array([1.0, 2.0, 4.0])
    assert analysis.representative_deviation(p0 * 1.1, p0) == pytest.approx(0.1, rel=1e-12)
    assert analysis.representative_deviation([1.1, 0.9], [1.0, 1.0], normaliser=2.0) == pytest.approx(0.05)


def test_discharge_volume_percentage_eq_6_2():
    assert np.allclose(analysis.discharged_volume_percentage(2.0, [2.0, 1.8, 0.0]), [0.0, 10.0, 100.0])


def test_outlet_mass_flow_of_a_uniform_profile():
    r = np.linspace(0, 0.1, 21)
    w = analysis.outlet_mass_flow(r, -np.full_like(r, 1.0), 1000.0)
    assert w == pytest.approx(1000.0 * math.pi * 0.1**2, rel=1e-12)  # ρ v π R²
    t = np.linspace(0, 1, 11)
    assert np.allclose(analysis.flow_rate_from_mass(t, 5.0 * t), 5.0)


def test_flow_channel_boundary_recovered_exactly():
    """A field whose |v_z| falls linearly to zero at r = b(z): the 0.001 criterion crosses at
    r = b(z)(1 − 0.001) exactly (linear interpolation of a linear profile); above z = 1 the
    whole row flows (mass flow) and the boundary is reported as nan."""
    z = np.linspace(0.05, 2.0, 40)
    r = np.linspace(0.0, 0.35, 71)
    R, Z = np.meshgrid(r, z)
    b = np.where(Z < 1.0, 0.05 + 0.3 * Z, 10.0)  # channel radius grows with height, then mass flow
    VZ = -np.clip(1.0 - R / b, 0.0, None) - np.where(Z >= 1.0, 0.0, 0.0)
    zr, fcb = analysis.flow_channel_boundary(R, Z, VZ, 1e-3)
    lower = zr < 1.0
    assert np.allclose(fcb[lower], (0.05 + 0.3 * zr[lower]) * (1 - 1e-3), rtol=0, atol=1e-12)
    assert np.all(np.isnan(fcb[~lower]))
    assert analysis.effective_transition(zr, fcb, np.full_like(zr, 0.35)) == pytest.approx(zr[~lower].min())
    # a channel whose boundary lies within one element of the wall meets it
    near = np.where(lower, fcb, 0.345)
    assert np.isnan(analysis.effective_transition(zr, near, np.full_like(zr, 0.35)))
    assert analysis.effective_transition(zr, near, np.full_like(zr, 0.35), tolerance=0.01) == pytest.approx(
        zr[~lower].min())
    # the same from scattered points
    zr2, fcb2 = analysis.flow_channel_boundary(R.ravel(), Z.ravel(), VZ.ravel(), 1e-3)
    assert np.allclose(fcb2[lower], fcb[lower], atol=1e-12)


def test_stress_ratio_and_orientation():
    # at rest in a silo: σ_zz more compressive -> major principal stress vertical (90°)
    sig = np.array([[-4.0, -10.0, -4.0, 0.0], [-10.0, -4.0, -4.0, 0.0], [-7.0, -7.0, -7.0, 3.0]])
    ang = analysis.stress_orientation(sig)
    assert ang[0] == pytest.approx(90.0) and ang[1] == pytest.approx(0.0)
    assert abs(ang[2]) == pytest.approx(45.0)
    p, q = analysis.invariants(sig[:1])
    assert p[0] == pytest.approx(6.0) and q[0] == pytest.approx(6.0)  # q = |σ_zz − σ_rr| here
    assert analysis.stress_ratio(sig[:1])[0] == pytest.approx(1.0)
    # strain rate: elongation along r -> major direction horizontal
    assert analysis.strain_rate_orientation([[1.0, -1.0, 0.0, 0.0]])[0] == pytest.approx(0.0)


def test_mobilised_friction_angle_of_known_states():
    """Rotated in-plane states of known principal pressures: σ1 3, σ3 1 → sin φ 0.5 (30°) whatever
    the rotation and whichever of rr/zz/θθ is which; b from the hoop stress; on the Drucker–Prager
    cone q = p tan β the angle at b = 0 and b = 1 is theory.mohr_coulomb_angle's compression and
    extension angle (the cone's strength range, to round-off)."""
    def state(s_a, s_b, s_hoop, angle):  # in-plane principal pressures s_a, s_b rotated by angle
        c, s = np.cos(angle), np.sin(angle)
        rr, zz, rz = s_a * c * c + s_b * s * s, s_a * s * s + s_b * c * c, (s_a - s_b) * c * s
        return [-rr, -zz, -s_hoop, -rz]

    sig = np.array([state(3.0, 1.0, 1.0, 0.3), state(1.0, 3.0, 2.0, -1.1), state(2.0, 1.0, 3.0, 0.7),
                    state(3.0, 3.0, 3.0, 0.0), state(-1.0, -2.0, -1.0, 0.2)])
    phi, b = analysis.mobilised_friction_angle(sig)
    assert np.allclose(phi[:3], 30.0, atol=1e-12) and np.allclose(b[:3], [0.0, 0.5, 0.5], atol=1e-12)
    assert phi[3] == 0.0 and np.isnan(b[3]) and np.isnan(phi[4])  # isotropic; all tension
    beta = 46.63
    t = np.tan(np.radians(beta))
    for bb, cone in ((0.0, "compression"), (1.0, "extension")):
        # σ3 = 1, σ2 = 1 + b(x − 1), σ1 = x on q = p tan β: (x − 1)(3√(1 − b + b²) − t(1 + b)) = 3t
        x = 1.0 + 3.0 * t / (3.0 * np.sqrt(1.0 - bb + bb * bb) - t * (1.0 + bb))
        phi, b = analysis.mobilised_friction_angle([state(x, 1.0, 1.0 + bb * (x - 1.0), 0.4)])
        assert phi[0] == pytest.approx(theory.mohr_coulomb_angle(beta, cone), abs=1e-9) and b[0] == pytest.approx(bb)


def test_wall_shear_capacity_on_and_inside_the_cone():
    """States put on the cone by their σ_rz: the capacity is that σ_rz over −σ_rr (round-off);
    the same normal stresses with any other σ_rz give the same capacity; with σ_zz = σ_θθ = a σ_rr
    it peaks at theory.drucker_prager_wall_shear_limit's a and equals that limit (1e-12); normal
    stresses alone outside the cone give 0, a tensile σ_rr NaN."""
    beta = theory.drucker_prager_cone(40.0, 10.0, "extension")[0]  # ch. 7's discharge cone
    t = np.tan(np.radians(beta))
    rng = np.random.default_rng(3)
    normals = -rng.uniform(1.0, 2.0, (200, 3))
    p = -normals.mean(axis=1)
    dev2 = ((normals + p[:, None]) ** 2).sum(axis=1)
    rz = np.sqrt(np.maximum(p * p * t * t - 1.5 * dev2, 0.0) / 3.0)
    on = np.column_stack([normals, rz])
    assert np.allclose(analysis.stress_ratio(on)[rz > 0], t, rtol=1e-12)  # on the cone indeed
    cap = analysis.wall_shear_capacity(on, t)
    assert np.allclose(cap, rz / -normals[:, 0], rtol=1e-12, atol=1e-15)
    on[:, 3] *= rng.uniform(-1.0, 1.0, 200)
    assert np.array_equal(analysis.wall_shear_capacity(on, t), cap)
    a_star = (9.0 + 2.0 * t * t) / (9.0 - 4.0 * t * t)
    a = np.linspace(0.2, 3.0, 2801)
    caps = analysis.wall_shear_capacity(np.column_stack([-np.ones_like(a), -a, -a, 0.0 * a]), t)
    assert abs(a[np.argmax(caps)] - a_star) < 2e-3
    limit = theory.drucker_prager_wall_shear_limit(beta)
    assert analysis.wall_shear_capacity([[-1.0, -a_star, -a_star, 0.0]], t)[0] == pytest.approx(limit, rel=1e-12)
    assert analysis.wall_shear_capacity([[-1.0, -20.0, -1.0, 0.0]], t)[0] == 0.0
    assert np.isnan(analysis.wall_shear_capacity([[0.5, -1.0, -1.0, 0.1]], t)[0])


def test_windowed_mass_flow_of_a_known_discharge():
    """M(t) = 30 t + 2 sin(2π t/10) sampled unevenly: each whole 10 s window's mean rate is
    exactly 30 kg/s (the sine integrates to zero over a period); a linear ramp's windows give
    its mean rate in each; a partial last window is dropped."""
    rng = np.random.default_rng(1)
    t = np.sort(np.concatenate([[0.0, 60.0], rng.uniform(0, 60, 3000)]))
    starts, w = analysis.windowed_mass_flow(t, 30 * t + 2 * np.sin(2 * np.pi * t / 10), 10.0)
    assert np.allclose(starts, [0, 10, 20, 30, 40, 50]) and np.allclose(w, 30.0, atol=0.05)
    starts, w = analysis.windowed_mass_flow(t, t**2, 25.0, t_start=5.0)  # rate 2t: mean over [a, a+25]
    assert np.allclose(starts, [5.0, 30.0]) and np.allclose(w, [2 * 17.5, 2 * 42.5], rtol=1e-3)


def test_janssen_comparison_on_janssen_itself():
    """A wall carrying exactly Janssen's pressure at the friction limit: ratio 1 and slip
    fraction 1 over the window from z0 = R/(2Kμ) below the surface down to z_min; halve the
    shear on the lower half and the fraction halves."""
    from silo_dolfinx import theory

    H, R, mu, K, g = 4.0, 0.35, 0.63, 0.38, 14270.0
    z = np.linspace(0, H, 401)
    ph, _, _ = theory.janssen(H - z, R, mu, K, g)
    c = analysis.janssen_comparison(z, ph, mu * ph, fill_height=H, radius=R, mu=mu, k=K, unit_weight=g, z_min=0.1)
    assert abs(c["z0"] - R / (2 * K * mu)) < 1e-12 and c["window"] == (0.1, H - c["z0"])
    assert abs(c["ratio_min"] - 1) < 1e-12 and abs(c["ratio_max"] - 1) < 1e-12 and c["slip_fraction"] == 1.0
    ps = np.where(z < c["z"].mean(), 0.5 * mu * ph, mu * ph)
    c = analysis.janssen_comparison(z, ph, ps, fill_height=H, radius=R, mu=mu, k=K, unit_weight=g, z_min=0.1)
    assert abs(c["slip_fraction"] - 0.5) < 0.01


def test_janssen_fit_recovers_k_and_mu():
    """Janssen pressures for (K, μ) = (0.6, 0.36) over a 4.3-m wall, with ±1 % noise of a fixed
    seed: the fit returns K and μ within 3 % (the noise moves the least-squares optimum by ~1 %
    of each), z0 and the level γR/(2μ) from them; the same curve with (K, μ) swapped to (0.36,
    0.6) has the same z0 and a level 0.6 as high - the two quantities the fit separates. Too
    few points in the window is an error."""
    from silo_dolfinx import theory

    H, R, g = 5.0, 0.35, 15000.0
    z = np.linspace(1.0, H, 200)
    rng = np.random.default_rng(7)
    for k, mu in ((0.6, 0.36), (0.36, 0.6)):
        ph = theory.janssen(H - z, R, mu, k, g)[0] * (1 + 0.01 * rng.standard_normal(z.size))
        f = analysis.janssen_fit(z, ph, fill_height=H, radius=R, unit_weight=g, z_min=1.0)
        assert abs(f.k / k - 1) < 0.03 and abs(f.mu / mu - 1) < 0.03, (f, k, mu)
        assert abs(f.z0 / (R / (2 * k * mu)) - 1) < 0.03 and abs(f.p_inf / (g * R / (2 * mu)) - 1) < 0.03
        assert f.rms < 0.02 * ph.max()
    with pytest.raises(ValueError, match="at least three"):
        analysis.janssen_fit(z, ph, fill_height=H, radius=R, unit_weight=g, z_min=4.99)


# ------------------------------------------------------------------ ch. 4 dynamic wall pressure
def test_windowed_spectra_follow_a_tone_that_changes():
    """Six consecutive 5-s windows (Fig. 4-12) of a record whose wave is 5 Hz for 15 s, then
    7 Hz: the first three windows peak at 5 Hz, the last three at 7 Hz, each within one bin
    (0.2 Hz); a seventh window past the record's end is left out."""
    rate = 200.0
    t = np.arange(0.0, 30.0 + 0.5 / rate, 1.0 / rate)
    x = 5000.0 + np.where(t < 15.0, 100.0 * np.sin(2 * math.pi * 5.0 * t), 100.0 * np.sin(2 * math.pi * 7.0 * t))
    spectra = analysis.windowed_spectra(t, x, 0.0, 5.0, 7)
    assert len(spectra) == 6
    for i, sp in enumerate(spectra):
        assert abs(sp.resolution - 0.2) < 1e-3
        assert abs(sp.peaks(1, min_frequency=1.0)[0] - (5.0 if i < 3 else 7.0)) < sp.resolution


def test_averaged_spectrum_finds_a_drifting_wave_a_single_spectrum_misses():
    """The fill's wave drifts up as the fill drains (eq. 4-12: f ∝ 1/h). A 100-Pa tone drifting
    from 5.0 to 6.0 Hz over 30 s (the fill 17 % lower at the end) beside a steady 40-Pa tone at
    9 Hz: one periodogram of the record (bins of 1/30 Hz) spreads the drifting tone over ~30
    bins (its largest, 36 Pa) and its largest peak is the steady tone; Welch's average of 5-s
    windows (0.2-Hz bins, 0.17 Hz of drift in each) keeps it in a bin or two (57 Pa) and finds
    it within the drift's range. A pure tone on a bin centre shows its amplitude (100 Pa
    within 1 %: the amplitude scaling)."""
    rate = 200.0
    t = np.arange(0.0, 30.0, 1.0 / rate)
    phase = 2 * math.pi * (5.0 * t + 0.5 * (1.0 / 30.0) * t**2)  # f(t) = 5.0 + t/30
    x = 4000.0 + 100.0 * np.sin(phase) + 40.0 * np.sin(2 * math.pi * 9.0 * t)
    assert abs(analysis.spectrum(t, x).peaks(1, min_frequency=1.0)[0] - 9.0) < 0.05
    avg = analysis.averaged_spectrum(t, x, segments=6)
    assert abs(avg.resolution - 0.2) < 0.01
    assert 5.0 <= avg.peaks(1, min_frequency=1.0)[0] <= 6.0
    # a peak just above the cutoff bin whose refined frequency lies below it is not reported
    near = analysis.averaged_spectrum(t, 100.0 * np.sin(2 * math.pi * 0.93 * t) + 20.0 * np.sin(2 * math.pi * 7.0 * t))
    assert np.all(near.peaks(2, min_frequency=1.0) >= 1.0)
    tone = analysis.averaged_spectrum(t, 100.0 * np.sin(2 * math.pi * 6.0 * t), segments=6)
    assert abs(tone.amplitude.max() / 100.0 - 1.0) < 0.01


def test_switch_time_finds_when_the_pressure_leaves_the_filled_state():
    """A station at 10 kPa that falls to 4 kPa over 0.5 s starting 3 s after the opening (a
    slow controlled discharge), with a 5-Hz wave and a 0.3-Hz fluctuation riding on the flowing
    state: the switch is halfway down, 3.25 s after opening, found within 0.1 s (the 1-Hz
    filter smooths the ramp symmetrically: zero phase). Higher up the wall the flow raises the
    pressure: the same with the step upwards. The report measures from 1 s after it."""
    t = np.arange(0.0, 20.0, 0.005)
    ramp = np.clip((t - 3.0) / 0.5, 0.0, 1.0)
    flowing = 300.0 * np.sin(2 * math.pi * 0.3 * t) * ramp + 200.0 * np.sin(2 * math.pi * 5.0 * t)
    for start, end in ((10000.0, 4000.0), (4000.0, 9000.0)):
        p = start + (end - start) * ramp + flowing
        assert abs(analysis.switch_time(t, p, 0.0) - 3.25) < 0.1


def test_low_frequency_fluctuation_of_a_known_signal():
    """p = 8000 + 300 sin(2π 0.4 t) + 200 sin(2π 5.2 t) over 20 s: the < 1 Hz part has RMS
    300/√2 = 212.1 within 2 % (the filter passes 0.4 Hz at |H|² = 0.9993; the RMS is taken over
    the 16 s inside the filter's end effects, 6.4 periods, where the mean of sin² may differ from
    ½ by up to 1/(4π f T) = 1.2 %) and its frequency is 0.4 Hz within one bin
    (0.05 Hz); the 5.2 Hz wave alone gives < 1 % of its amplitude: the filter attenuates it by
    ~10⁻⁵·⁸, but the linear trend fitted to 104 periods of it (removed with the record's drain)
    is itself slow, of order A/(π·104) = 0.6 Pa. The part above 1 Hz is the wave's."""
    rate = 200.0
    t = np.arange(0.0, 20.0, 1.0 / rate)
    low = 300.0 * np.sin(2 * math.pi * 0.4 * t)
    rms, f = analysis.low_frequency_fluctuation(t, 8000.0 + low + 200.0 * np.sin(2 * math.pi * 5.2 * t))
    assert rms == pytest.approx(300.0 / math.sqrt(2.0), rel=0.02)
    assert abs(f - 0.4) < 1.0 / 20.0
    rms_wave, _ = analysis.low_frequency_fluctuation(t, 8000.0 + 200.0 * np.sin(2 * math.pi * 5.2 * t))
    assert rms_wave < 1e-2 * 200.0
    # the rest, above 1 Hz: the wave's 200/√2 = 141.4 Pa within 2 % (the 0.4-Hz part leaves
    # |1 − |H|²| = 7e-4 of itself behind; the trend fit's 0.6 Pa)
    fast = analysis.fast_fluctuation(t, 8000.0 + low + 200.0 * np.sin(2 * math.pi * 5.2 * t))
    assert fast == pytest.approx(200.0 / math.sqrt(2.0), rel=0.02)


def test_windowed_low_fluctuation_leaves_out_a_slow_recovery():
    """A station recovering after its switch, p = 8000 − 3000 e^(−t/8 s) + 300 sin(2π 0.4 t) +
    200 sin(2π 5.2 t) over 24 s. In three 8-s windows, each detrended alone, the < 1 Hz RMS is
    the 0.4-Hz sine's 300/√2 = 212.1 within 6 %: the first window keeps the recovery's bend
    about its line (RMS 0.023 × 3000 = 69 Pa in a third of the record: +1.8 %), and each 6-s
    interior holds 2.4 periods, so its mean of sin² is ½ within 1/(4π·0.4·6) = 3 % (219.4
    measured; 215.0 without the recovery). Over the whole record, detrended once, the recovery's
    curvature reads as fluctuation: 317 Pa, +49 %."""
    rate = 200.0
    t = np.arange(0.0, 24.0, 1.0 / rate)
    sine = 300.0 * np.sin(2 * math.pi * 0.4 * t) + 200.0 * np.sin(2 * math.pi * 5.2 * t)
    p = 8000.0 - 3000.0 * np.exp(-t / 8.0) + sine
    assert analysis.windowed_low_fluctuation(t, p, window=8.0) == pytest.approx(300.0 / math.sqrt(2.0), rel=0.06)
    assert analysis.low_frequency_fluctuation(t, p)[0] > 1.4 * 300.0 / math.sqrt(2.0)
    assert analysis.windowed_low_fluctuation(t, 8000.0 + sine, window=8.0) == pytest.approx(300.0 / math.sqrt(2.0),
                                                                                          rel=0.04)


def test_mobilised_friction_and_slip_fraction():
    """|p_s|/p_n where loaded (NaN where not); the fraction of samples sliding."""
    m = analysis.mobilised_friction([1000.0, 2000.0, 0.0], [-267.0, 540.0, 5.0])
    assert m[0] == pytest.approx(0.267) and m[1] == pytest.approx(0.27) and np.isnan(m[2])
    assert analysis.slip_fraction([-0.2, -0.1, 0.0, 1e-6, -0.05]) == pytest.approx(0.6)


def test_station_means_and_overpressure():
    """Two stations with known histories: their eq. 4-9 means over [1, 3] s, and the
    overpressure against a linear fill profile p = 1000 (2 − z)."""
    t = np.arange(0.0, 4.0, 0.01)
    hist = {"t": np.concatenate([t, t]), "station": np.repeat([0.0, 1.0], t.size),
            "z": np.concatenate([np.full(t.size, 0.5), np.full(t.size, 1.5)]),
            "p_n": np.concatenate([2000.0 + 100.0 * np.sin(2 * math.pi * t), 600.0 + 0.0 * t])}
    z, p = analysis.station_means(hist, 1.0, 3.0)
    assert z == pytest.approx([0.5, 1.5]) and p == pytest.approx([2000.0, 600.0], rel=1e-3)
    ratio = analysis.overpressure(z, p, [0.0, 2.0], [2000.0, 0.0])
    assert ratio == pytest.approx([2000.0 / 1500.0, 600.0 / 500.0], rel=1e-3)


def test_wall_mean_converges_where_the_nodal_peak_does_not():
    """A wall profile with a corner singularity, p = 5 kPa + 1 kPa·(|s − 1|/0.05 m)^(−1/3)
    (the trace of a singular stress), sampled on nodes h apart, corner on a node taking the
    value half a cell away: the singular part of the nodal peak grows as h^(−1/3) (26 % per
    halving; the peak 7 %, as ch. 7's corner did), the mean over ±0.05 m of the corner
    converges to the exact 5 + 1.5 = 6.5 kPa as h^(2/3) (errors 2.9, 1.8, 1.1 %: the
    interpolation between nodes misses part of the singular integral). A
    linear profile's mean is exact; a window past the profile's end is refused."""
    exact = 5000.0 + 1000.0 * 1.5  # ∫_0^w (s/w)^(-1/3) ds / w = 3/2
    peaks, means = [], []
    for h in (0.02, 0.01, 0.005):
        s = np.arange(0.0, 2.0 + h / 2, h)
        with np.errstate(divide="ignore"):
            p = 5000.0 + 1000.0 * (np.abs(s - 1.0) / 0.05) ** (-1.0 / 3.0)
        p[np.abs(s - 1.0) < 1e-9] = 5000.0 + 1000.0 * (0.5 * h / 0.05) ** (-1.0 / 3.0)  # the nodal value grows
        peaks.append(p.max())
        means.append(analysis.wall_mean(s, p, 1.0, 0.05))
    assert peaks[2] / peaks[1] > 1.06 and peaks[1] / peaks[0] > 1.06
    err = [abs(m / exact - 1) for m in means]
    assert err[2] < 0.015 and err[0] / err[1] > 1.4 and err[1] / err[2] > 1.4  # 2^(2/3) = 1.59
    s = np.linspace(0.0, 1.0, 11)
    assert analysis.wall_mean(s[::-1], 100.0 * s[::-1], 0.5, 0.23) == pytest.approx(50.0)
    with pytest.raises(ValueError, match="window"):
        analysis.wall_mean(s, s, 0.98, 0.05)


# ------------------------------------------------------------------ ch. 5 rarefaction waves
def test_rarefaction_growth_recovers_the_exponent_of_a_travelling_front():
    """A front of amplitude 3500·exp(0.33 x) Pa travels up a 5-m column at 47 m/s (FE-1's
    confined wave speed) on a 22-kPa state, rises over 5 ms (the pull of eq. 5-17) and
    reflects from the top as a compression that overshoots the initial state; 1 % noise on
    top. With rise = 6 ms (the front passes in ~5 ms) the exponent comes back within 2 % and
    inside three standard errors, σ⁺0 within 2 %; stations whose front has not passed before
    the reflection comes (x > L − c·rise = 4.72 m) get no amplitude. A reflection that is a
    rarefaction too (a rigid top) leaves the fit unchanged while the windows keep it out, and
    spoils it when they let it in (a wave speed taken 30 % too low)."""
    c, L, b, a0, s0 = 47.0, 5.0, 0.33, 3500.0, 22000.0
    t = np.arange(0.0, 0.35, 2e-4)
    x = np.linspace(0.25, 4.95, 20)
    rng = np.random.default_rng(1)

    def rise(tt):
        return 0.5 * (1.0 + np.tanh((tt - 0.0025) / 0.0012))

    amp = a0 * np.exp(b * x)[:, None]
    values = (s0 - amp * rise(t[None, :] - 0.02 - x[:, None] / c)
              + 1.5 * amp * rise(t[None, :] - 0.02 - (2 * L - x[:, None]) / c))
    values += 0.01 * a0 * rng.standard_normal(values.shape)
    pull, fit = analysis.Pull(0.02, c, L, 0.006), (0.5, None)
    g = analysis.rarefaction_growth(t, x, values, pull, fit)
    assert abs(g.exponent / b - 1.0) < 0.02 and 0.0 < g.stderr < 0.02 * b
    assert abs(g.sigma0 / a0 - 1.0) < 0.02
    assert np.isnan(g.amplitude[-1]) and g.window[1] <= L - c * 0.006
    # σ⁺0 given (the boundary's ρ c u0): the one-parameter fit through it, and a σ⁺0 twice
    # too small raises every ln ratio by ln 2, which the slope through the origin absorbs
    fixed = analysis.rarefaction_growth(t, x, values, pull, fit, sigma0=a0)
    assert abs(fixed.exponent / b - 1.0) < 0.02 and fixed.sigma0 == a0
    low = analysis.rarefaction_growth(t, x, values, pull, fit, sigma0=a0 / 2)
    assert low.exponent > 1.2 * b
    # a record that ends inside the lower stations' windows: the ends are no wave
    cut = t < 0.12
    short = analysis.rarefaction_growth(t[cut], x, values[:, cut], pull, fit)
    assert abs(short.exponent / b - 1.0) < 0.02
    assert np.all(np.abs(g.normalised[x < 4.5] / np.exp(b * x[x < 4.5]) - 1.0) < 0.05)
    # a window running into a second rarefaction (here: the reflection taken as one, sign
    # flipped, as from a rigid top) is what the windows keep out: that fit is off
    back = a0 * np.exp(b * L)  # what reached the top, on its way down
    rigid = values - 1.5 * amp * rise(t[None, :] - 0.02 - (2 * L - x[:, None]) / c) - back * rise(
        t[None, :] - 0.02 - (2 * L - x[:, None]) / c)
    assert abs(analysis.rarefaction_growth(t, x, rigid, pull, fit).exponent / b - 1.0) < 0.02
    late = analysis.rarefaction_growth(t, x, rigid, analysis.Pull(0.02, 0.7 * c, L, 0.006), fit)
    assert abs(late.exponent / b - 1.0) > 0.1


def test_discharged_volume_and_steady_flow_on_known_series():
    """Eq. 6-2 in mass; the time a series first reaches a level (interpolated; nan if never);
    the steady-flow start of a flow that ramps up over 3 s and then holds is the first whole
    window at the constant rate (3 s), and a flow that keeps growing (at any
    rate: its last windows drift) is never steady."""
    t = np.linspace(0.0, 20.0, 4001)
    rate = np.minimum(t / 3.0, 1.0) * 30.0
    mass = np.concatenate([[0.0], np.cumsum(0.5 * (rate[1:] + rate[:-1]) * np.diff(t))])
    v = analysis.discharged_percentage(mass, 1000.0)
    assert v[-1] == pytest.approx(100 * (30 * 20 - 45) / 1000, rel=1e-6)
    assert analysis.first_time_reaching(t, v, 4.5) == pytest.approx(3.0, abs=1e-6)  # 45 kg at 3 s
    assert np.isnan(analysis.first_time_reaching(t, v, 100.0))
    assert analysis.steady_flow_start(t, mass, 1.0, 0.1) == pytest.approx(3.0)
    growing = 0.5 * t ** 2
    assert np.isnan(analysis.steady_flow_start(t, growing, 1.0, 0.1))


def test_cell_oscillation_sees_a_checkerboard_and_not_a_linear_field():
    """Cell minus the mean of its edge neighbours: 0 inside a linear field, ±2a for a ±a
    checkerboard (the issue's q/p mode above an outlet), on a 6 × 5 grid of unit-aspect cells."""
    xs, zs = np.arange(7) * 0.1, np.arange(6) * 0.1
    corners = np.array([[[xs[i], zs[j]], [xs[i + 1], zs[j]], [xs[i + 1], zs[j + 1]], [xs[i], zs[j + 1]]]
                        for j in range(5) for i in range(6)])
    linear = np.array([2 * xs[i] + 3 * zs[j] for j in range(5) for i in range(6)])
    board = np.array([(-1.0) ** (i + j) for j in range(5) for i in range(6)])
    inner = np.zeros((5, 6), bool)
    inner[1:-1, 1:-1] = True
    inner = inner.ravel()
    assert np.abs(analysis.cell_oscillation(corners, linear)[inner]).max() < 1e-12
    assert np.allclose(np.abs(analysis.cell_oscillation(corners, board)[inner]), 2.0, rtol=1e-12)


def test_time_averaged_velocity_of_snapshots(tmp_path):
    """The mean of the snapshots' node velocities (a wave that reverses averages out), at the
    last snapshot's node positions."""
    xy = np.array([[0.0, 0.0], [0.1, 0.0]])
    files = []
    for i, vz in enumerate((-1.0, -3.0, -2.0)):
        f = tmp_path / f"snapshot_{i}.npz"
        np.savez(f, node_xy=xy + 0.01 * i, node_velocity=np.array([[0.0, vz], [0.5 * (-1) ** i, 0.0]]))
        files.append(f)
    pos, v = analysis.time_averaged_velocity(files)
    assert np.allclose(pos, xy + 0.02) and np.allclose(v, [[0.0, -2.0], [0.5 / 3, 0.0]])


def test_time_averaged_velocity_keeps_to_the_last_mesh(tmp_path):
    """A rezoned run's snapshots: two on the first mesh (two nodes), two on the second (three
    nodes, ``mesh`` = 1): the mean is over the last two only, at the last one's nodes."""
    files = []
    for i, (mesh, n, vz) in enumerate([(0, 2, -9.0), (0, 2, -9.0), (1, 3, -1.0), (1, 3, -3.0)]):
        f = tmp_path / f"snapshot_{i}.npz"
        np.savez(f, mesh=mesh, node_xy=np.full((n, 2), float(i)), node_velocity=np.tile([0.0, vz], (n, 1)))
        files.append(f)
    pos, v = analysis.time_averaged_velocity(files)
    assert pos.shape == (3, 2) and np.allclose(pos, 3.0) and np.allclose(v, [0.0, -2.0])


def test_windowed_transitions_reads_each_window_on_its_own(tmp_path):
    """Two 5-s windows of snapshots whose flow channels (|v_z| falling linearly to zero at
    r = b(z), b growing to the wall's 0.35 m at z_e, the whole section flowing above) meet the
    wall at z_e = 0.8 m and then 1.2 m: each window gives its own z_e, to within one row of
    the boundary's sampling (1.92/59 = 0.033 m) plus one row of the nodes (0.025 m) that
    the interpolation onto those rows spans; a mix of the windows would land between the two.
    A third window holding a single snapshot (t = 0) is left out."""
    r, z = np.meshgrid(np.linspace(0.0, 0.35, 36), np.linspace(0.0, 2.0, 81))
    xy = np.column_stack([r.ravel(), z.ravel()])
    files = []
    for t in range(11):
        z_e = 0.8 if t <= 5 else 1.2
        b = np.where(z < z_e, 0.05 + 0.30 * z / z_e, 10.0)
        vz = -np.clip(1.0 - r / b, 0.0, None)
        f = tmp_path / f"snapshot_{t}.npz"
        np.savez(f, node_xy=xy, node_velocity=np.column_stack([np.zeros(vz.size), vz.ravel()]))
        files.append((float(t), f))
    ends, heights = analysis.windowed_transitions(files, 5.0, lambda zz: np.full_like(zz, 0.35), t_start=-5.0)
    assert np.allclose(ends, [5.0, 10.0])
    assert np.all(np.abs(heights - [0.8, 1.2]) <= 0.033 + 0.025), heights


def test_mode_shape_recovers_a_drifting_mode_beside_a_larger_slow_one():
    """Four signals share an oscillation drifting 33-37 Hz with the amplitudes 1, 0.5, −0.4
    (against the reference) and 0.8 lagging 30°; each also carries an 8-Hz swing three times
    larger (outside the band) and a signal of white noise alone rides along. The ratios come back
    to 0.1 % and 0.1° (measured 1e-8: the band holds the same mode in every row, and a Hann
    segment of 1 s leaks the 8-Hz swing into 30-40 Hz by less than 1e-6), the coherence of the
    shared mode above 0.99, of the noise below 0.05 (measured 0.003-0.023 over ten seeds: the
    band sums ~50 bins of 15 segments)."""
    rate, T = 200.0, 8.0
    t = np.arange(0.0, T, 1.0 / rate)
    rng = np.random.default_rng(3)
    phase = 2 * np.pi * (35.0 * t + 2.0 / (2 * np.pi * 0.3) * np.sin(2 * np.pi * 0.3 * t))  # 35 ± 2 Hz
    shape = np.array([1.0, 0.5, -0.4, 0.8 * np.exp(-1j * np.pi / 6)])
    rows = [np.real(a * np.exp(1j * phase)) + 3.0 * np.cos(2 * np.pi * 8.0 * t + k) for k, a in enumerate(shape)]
    rows.append(rng.normal(size=t.size))
    m = analysis.mode_shape(t, rows, (30.0, 40.0))
    assert np.allclose(np.abs(m.ratio[:4]), np.abs(shape), rtol=1e-3)
    assert np.allclose(np.angle(m.ratio[:4] / shape), 0.0, atol=np.radians(0.1))
    assert m.in_phase[2] < 0 < m.in_phase[1]
    assert np.all(m.coherence[:4] > 0.99) and m.coherence[4] < 0.05
    with pytest.raises(ValueError, match="band"):
        analysis.mode_shape(t, rows, (101.0, 110.0))


def test_travelling_wave_recovers_speed_direction_and_growth_and_tells_a_standing_wave():
    """A wave at 35 Hz climbing at 39 m/s and growing as e^{0.5 z} (the ch. 7 bin's, measured)
    at 15 heights 0.2 m apart, through `mode_shape` with 2 % noise on every record: speed and
    growth within 0.1 %, phase residual below 0.5° (measured 3e-5, 1.4e-4 and 0.02°: the noise
    is 1e-4 of the band's power). The same wave running down has the speed's sign flipped; a
    standing wave cos(kz) cos(ωt) of the same wavelength leaves a residual above 30° (88°: its
    phase jumps by π at each node)."""
    rate, T, f, c, g = 200.0, 6.0, 35.0, 39.0, 0.5
    t = np.arange(0.0, T, 1.0 / rate)
    z = np.arange(0.8, 3.61, 0.2)
    k = 2 * np.pi * f / c
    rng = np.random.default_rng(5)
    noise = lambda: 0.02 * rng.normal(size=t.size)  # noqa: E731
    for direction in (1.0, -1.0):
        rows = [np.exp(g * zi) * np.cos(2 * np.pi * f * t - direction * k * zi) + noise() for zi in z]
        m = analysis.mode_shape(t, rows, (31.0, 39.0), reference=len(z) - 1)
        w = analysis.travelling_wave(z, m.ratio, f)
        assert w.speed == pytest.approx(direction * c, rel=1e-3)
        assert w.growth == pytest.approx(g, rel=1e-3)
        assert w.phase_residual < np.radians(0.5)
    rows = [np.cos(k * zi) * np.cos(2 * np.pi * f * t) + noise() for zi in z]
    m = analysis.mode_shape(t, rows, (31.0, 39.0), reference=0)
    assert analysis.travelling_wave(z, m.ratio, f).phase_residual > np.radians(30.0)
    with pytest.raises(ValueError, match="three"):
        analysis.travelling_wave(z[:2], m.ratio[:2], f)


def test_slow_part_keeps_what_is_below_1_hz_thinned_to_eight_samples_a_period():
    """800 sin(2π 0.7 t) + 150 sin(2π 5 t) + a linear drift over 60 s at 200 Hz: the slow part
    is the 0.7-Hz tone scaled by the zero-phase filter's |H|² = 1/(1 + 0.7⁸) = 0.9455, within 1 %
    of 800 (the amplitude of a least-squares fit of the tone: exact at any sampling, where the
    samples 1/8 s apart may miss the peak by 1 − cos(π 0.7/8) = 3.8 %), and nothing else but a
    straight line (the linear trend removed with the drift is fitted to the tone too, an
    offset of ~20 Pa, 2.3 %, fitted here with it): the 5-Hz wave gone, residue < 1 % of 800;
    samples 1/8 s apart away from the filter's end effects."""
    t = np.arange(0.0, 60.0, 0.005)
    ts, slow = analysis.slow_part(t, 3000.0 + 20.0 * t + 800.0 * np.sin(2 * math.pi * 0.7 * t)
                                  + 150.0 * np.sin(2 * math.pi * 5.0 * t))
    assert np.diff(ts) == pytest.approx(np.full(ts.size - 1, 0.125), rel=1e-9)
    assert ts[0] >= 1.0 and ts[-1] <= 59.0  # the filter's end effects reach 1/cutoff into the record
    basis = np.column_stack([np.sin(2 * math.pi * 0.7 * ts), np.cos(2 * math.pi * 0.7 * ts), np.ones_like(ts), ts])
    coef, *_ = np.linalg.lstsq(basis, slow, rcond=None)
    assert math.hypot(*coef[:2]) == pytest.approx(800.0 / (1.0 + 0.7**8), rel=0.01)
    assert np.max(np.abs(slow - basis @ coef)) < 0.01 * 800.0


def test_low_correlation_finds_the_delay_and_sign_of_a_following_signal_under_a_fast_wave():
    """b is −a delayed by 0.3 s, buried under a 5-Hz wave three times a's RMS and white noise:
    below 1 Hz b follows a by +0.3 s within the thinned sampling's 1/8 s, r < −0.95 (the slow
    parts differ by the white noise's residue below 1 Hz, 0.2 × √(2·1 Hz/200 Hz) = 2 % of a's
    RMS, and the filter's end effects); swapped, the lag changes sign."""
    t = np.arange(0.0, 60.0, 0.005)
    a = slow_noise(t, seed=1)
    b = -np.interp(t - 0.3, t, a) + 3.0 * np.sin(2 * math.pi * 5.0 * t) \
        + 0.2 * np.random.default_rng(2).standard_normal(t.size)
    lag, r = analysis.low_correlation(t, a, b)
    assert abs(lag - 0.3) <= 0.125 and r < -0.95
    lag, r = analysis.low_correlation(t, b, a)
    assert abs(lag + 0.3) <= 0.125 and r < -0.95


def test_chance_correlation_tells_a_real_follower_from_a_search_that_finds_anything():
    """Searches over ten independent slow rows (0.5-Hz noise, 60 s: about 60 independent samples
    each, lags ± 1 s) find a best |r| of 0.25-0.4 by chance: the 95 % chance level lies at
    0.25-0.55 (0.31-0.47 in these 20) and, over 20 independent trials, is exceeded in at most 3 (a binomial count with
    p = 0.05: P(≥ 4 of 20) = 1.6 %); a row that is the signal delayed lies far above it. A
    periodic signal correlates with its own shifts: a 0.7-Hz tone's chance level is above 0.7
    and 1.5 × the noise's - a follower of a tone cannot be told from chance, why the report
    gives the level beside r."""
    t = np.arange(0.0, 60.0, 0.005)
    m = 8  # ± 1 s at 1/8 s
    levels, exceeded = [], 0
    for trial in range(20):
        ts, a = analysis.slow_part(t, slow_noise(t, seed=1000 + trial))
        rows = np.array([analysis.slow_part(t, slow_noise(t, seed=100 * trial + k))[1] for k in range(10)])
        levels.append(analysis.chance_correlation(a, rows, m))
        exceeded += max(abs(analysis.best_lag(a, row, m)[1]) for row in rows) > levels[-1]
    assert exceeded <= 3 and 0.25 < min(levels) and max(levels) < 0.55
    assert analysis.best_lag(a, np.roll(a, 3), m) == (3, pytest.approx(1.0, abs=0.02))  # 0.375 s later
    tone = np.sin(2 * math.pi * 0.7 * ts)
    tone_level = analysis.chance_correlation(tone, np.array([np.roll(tone, 3)]), m)
    assert tone_level > max(0.7, 1.5 * np.median(levels))


def test_failure_front_passes_a_band_once_every_band_below_has_failed():
    """Six bands (centres 0.1-1.1 m) sampled every 10 ms: band 0 failed at the start (not part
    of the front), bands 1-4 reach 10 % at yield at 0.2 z s (a front climbing at 5 m/s: each
    arrival exact to the sample, the share jumping from 0 to 0.3 between two), band 5 - the
    free surface - flickers to 0.5 at 0.05 s but is passed only after band 4; a band empty at
    the start (NaN) is left out. Where a band never fails the front stops below it. front_speed: 5 m/s over bands 1-4 to round-off, inf for bands
    failing at once."""
    t = np.arange(0.0, 1.0, 0.01)
    z = np.array([0.1, 0.3, 0.5, 0.7, 0.9, 1.1, 1.3])
    shares = np.zeros((7, t.size))
    shares[0] = 0.8
    for k in range(1, 5):
        shares[k, t >= 0.2 * z[k] - 1e-9] = 0.3
    shares[5, t >= 0.05 - 1e-9] = 0.5
    shares[6] = np.nan
    ta, za, fresh = analysis.failure_front(t, z, shares)
    assert fresh == 5 and za == pytest.approx(z[1:6])
    # first_time_reaching interpolates 0 → 0.3 to 0.1: a third of a sample before each arrival
    assert ta == pytest.approx(np.append(0.2 * z[1:5], 0.2 * z[4]) - 0.01 * 2 / 3, abs=1e-12)
    # band 3 never fails (a front that stalls at 0.5 m): bands 4 and 5 above it are not passed,
    # however early they fail
    shares[3] = 0.0
    ta, za, fresh = analysis.failure_front(t, z, shares)
    assert fresh == 5 and za == pytest.approx(z[1:3]) and ta == pytest.approx(0.2 * z[1:3] - 0.01 * 2 / 3)
    assert analysis.front_speed(ta[:4], za[:4]) == pytest.approx(5.0, rel=1e-9)
    assert analysis.front_speed(np.ones(3), [0.1, 0.2, 0.3]) == np.inf


def test_front_growth_tells_a_diffusing_front_from_one_at_a_constant_speed():
    """Arrivals of a front at heights h = √(1.5 t) (a diffusing one) are fitted with exponent ½
    and h²/t = 1.5 to round-off; h = 0.6 t (a constant speed) with exponent 1; the instant
    failure at the source (t ≈ 0, below 5 % of the last arrival) is left out, and a front with
    fewer than three later arrivals, or all at once, gives NaNs."""
    h = np.linspace(0.1, 2.5, 19)
    t = h**2 / 1.5
    exponent, coefficient = analysis.front_growth(np.append(1e-3, t), np.append(0.05, h))
    assert exponent == pytest.approx(0.5, abs=1e-9) and coefficient == pytest.approx(1.5, rel=1e-9)
    assert analysis.front_growth(h / 0.6, h)[0] == pytest.approx(1.0, abs=1e-9)
    assert np.isnan(analysis.front_growth([0.0, 1e-3, 1.0], [0.1, 0.2, 0.3])[0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no ill-conditioned fit: bands failing at once have no growth
        assert np.isnan(analysis.front_growth([1.0, 1.0, 1.0], [0.1, 0.2, 0.3])[0])


def _hump_records(seed: int, count: int = 6):
    """``count`` 30-s records at 200 Hz of a chaotic pulsing pressure: a broad resonance (white
    noise through the two-pole filter with poles 0.97 e^{±iω0}, ω0 = 5 Hz: a hump ~2 Hz wide,
    like point e's 3.8-5.9 Hz one), 100 Pa RMS, on a 300-Pa random walk and a 4-kPa mean; and
    the peak of the filter's power spectrum, cos ω_p = (1 + r²) cos ω0 / 2r (4.906 Hz)."""
    from scipy import signal as sps

    rate, r, w0 = 200.0, 0.97, 2 * math.pi * 5.0 / 200.0
    t = np.arange(0.0, 30.0, 1.0 / rate)
    rng = np.random.default_rng(seed)
    records = []
    for _ in range(count):
        hump = sps.lfilter([1.0], [1.0, -2 * r * math.cos(w0), r * r], rng.standard_normal(t.size + 2000))[2000:]
        walk = np.cumsum(rng.standard_normal(t.size))
        records.append((t, 4000.0 + 100.0 * hump / hump.std() + 300.0 * (walk - walk.mean()) / walk.std()))
    return records, math.acos((1 + r * r) * math.cos(w0) / (2 * r)) * rate / (2 * math.pi)


def test_ensemble_peak_finds_a_broad_humps_peak_one_realisation_misses():
    """A broad hump's highest bin hops from realisation to realisation (the ch. 4 point-e
    spectrum: 4.0-5.4 Hz between runs of one scene). Over 12 sets of six realisations, each
    realisation's own Welch peak (what `averaged_spectrum` reports) misses the hump's true
    4.906-Hz peak by 0.23 Hz in the median, the ensemble's by a third of that (0.33×): asked
    ≤ 0.5× (a mean of six independent peaks would give 1/√6 = 0.41× on average; one
    realisation's error, 1×, fails it), and its 90 % interval covers the true peak in at least 9
    of 12 (10 measured; the percentile bootstrap over six draws under-covers a little: 28 of 30
    in a trial). Each realisation's peak is exactly `averaged_spectrum`'s, and a tone common to
    all shows its amplitude (the scaling)."""
    single, ensemble, covered = [], [], 0
    for seed in range(12):
        records, true = _hump_records(seed)
        e = analysis.ensemble_peak(records, draws=300)
        single.extend(np.abs(e.each - true))
        ensemble.append(abs(e.frequency - true))
        covered += e.interval[0] <= true <= e.interval[1]
        if seed == 0:
            for (t, x), f in zip(records, e.each):
                assert f == analysis.averaged_spectrum(t, x).peaks(1, min_frequency=1.0)[0]
    assert np.median(ensemble) <= 0.5 * np.median(single), (np.median(ensemble), np.median(single))
    assert covered >= 9, covered
    t = np.arange(0.0, 30.0, 1.0 / 200.0)
    tone = analysis.ensemble_peak([(t, 100.0 * np.sin(2 * math.pi * 6.0 * t))] * 3, draws=10)
    assert abs(tone.frequency - 6.0) < 0.01 and abs(tone.spectrum.amplitude.max() / 100.0 - 1.0) < 0.01


def test_event_steps_tells_a_step_from_a_pulsing_records_own_steps():
    """A 500-Pa, 5-Hz wave with white noise (σ 50 Pa, 200 Hz) that steps up 200 Pa at 20 s;
    events at 20 s, 40 s (nothing happens) and 59.9 s (too near the end). With 0.4-s windows
    (two periods: the wave's mean is zero in each) the step is 200 Pa within 30 (the noise's
    two 80-sample means differ by σ·√(2/80) = 7.9 Pa: ~4σ), no quiet instant steps as much
    (exceedance 0), the null event is one of the quiet ones (exceedance > 0.05), the last gets
    NaN; the typical quiet step is the median |N(0, 7.9)| = 5.3 Pa within 30 %."""
    rate = 200.0
    t = np.arange(0.0, 60.0, 1.0 / rate)
    rng = np.random.default_rng(3)
    x = 5000.0 + 500.0 * np.sin(2 * math.pi * 5.0 * t) + 50.0 * rng.standard_normal(t.size) + 200.0 * (t > 20.0)
    st = analysis.event_steps(t, x, [20.0, 40.0, 59.9], 0.4, 0.0, 60.0)
    assert st.step[0] == pytest.approx(200.0, abs=30.0) and st.exceedance[0] == 0.0
    assert st.exceedance[1] > 0.05 and np.isnan(st.step[2]) and np.isnan(st.exceedance[2])
    assert st.typical == pytest.approx(0.674 * 50.0 * math.sqrt(2.0 / 80.0), rel=0.3)
