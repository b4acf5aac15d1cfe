"""Turning results into the thesis' numbers: averages, spectra, deviations, flow rates,
flow-channel boundaries and stress/strain-rate orientations. Plain numpy; no mesh needed.

Conventions as in the rest of the package: stress 4-vectors (rr, zz, θθ, rz), tension
positive; p = −tr σ/3 (compression positive), q = √(3 J2); heights up from the outlet.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from silo_dolfinx.geometry.cells import cell_areas
from silo_dolfinx.invariants import p_q, principal_values
from silo_dolfinx.invariants import stress_ratio as _ratio


# ---------------------------------------------------------------------------- time series
LOW_CUTOFF = 1.0  # Hz: the thesis' "< 1 Hz" slip-stick / intermittent-arching fluctuation


def time_average(t, values, t_start: float, t_end: float):
    """Eq. 4-9 / 6-1: mean of the samples with t_start ≤ t ≤ t_end (along axis 0)."""
    t = np.asarray(t, float)
    sel = (t >= t_start) & (t <= t_end)
    if not np.any(sel):
        raise ValueError(f"no samples in [{t_start}, {t_end}] s")
    return np.asarray(values, float)[sel].mean(axis=0)


def _window(t, x, t_start, t_end, min_samples: int, what: str):
    """The samples with t_start ≤ t ≤ t_end (either bound optional), at least min_samples."""
    t = np.asarray(t, float)
    x = np.asarray(x, float)
    sel = np.ones(t.size, bool)
    if t_start is not None:
        sel &= t >= t_start
    if t_end is not None:
        sel &= t <= t_end
    if sel.sum() < min_samples:
        raise ValueError(f"need at least {min_samples} samples for {what}")
    return t[sel], x[sel]


@dataclass
class Spectrum:
    frequency: np.ndarray  # Hz
    amplitude: np.ndarray  # one-sided amplitude, same unit as the signal
    resolution: float  # Hz, the bin width 1/T

    def peaks(self, n: int = 2, min_frequency: float = 0.0, min_separation: float | None = None) -> np.ndarray:
        """Frequencies of the n largest local maxima above min_frequency, at least
        min_separation apart (default: 3 bins), largest first; quadratic interpolation
        refines each within its bin (a peak that this moves below min_frequency is not one)."""
        f, a = self.frequency, self.amplitude
        sep = 3 * self.resolution if min_separation is None else min_separation
        idx = [i for i in range(1, len(a) - 1) if a[i] >= a[i - 1] and a[i] >= a[i + 1] and f[i] >= min_frequency]
        idx.sort(key=lambda i: -a[i])
        chosen: list[float] = []
        for i in idx:
            y0, y1, y2 = a[i - 1], a[i], a[i + 1]
            den = y0 - 2 * y1 + y2
            shift = 0.5 * (y0 - y2) / den if den != 0 else 0.0
            fi = f[i] + shift * self.resolution
            if fi >= min_frequency and all(abs(fi - c) >= sep for c in chosen):
                chosen.append(fi)
            if len(chosen) == n:
                break
        return np.array(chosen)


def spectrum(t, x, *, detrend: str = "linear", window: str = "hann", t_start: float | None = None,
             t_end: float | None = None) -> Spectrum:
    """One-sided amplitude spectrum of a uniformly sampled signal (thesis Figs. 4-11, 4-12).

    The signal is detrended (constant or linear) and windowed (Hann by default); amplitudes
    are corrected for the window's coherent gain, so a sine of amplitude A shows A. The
    resolution is 1/T for a record of length T."""
    from scipy import signal as sps

    t, x = _window(t, x, t_start, t_end, 8, "a spectrum")
    dt = np.diff(t)
    if np.max(np.abs(dt - dt.mean())) > 1e-3 * dt.mean():
        # resample onto a uniform grid (histories are written at a fixed rate, but a stage
        # boundary may add a sample)
        tu = np.linspace(t[0], t[-1], t.size)
        x = np.interp(tu, t, x)
        t = tu
    n = t.size
    step = (t[-1] - t[0]) / (n - 1)
    x = sps.detrend(x, type=detrend) if detrend else x - 0.0
    w = sps.get_window(window, n) if window else np.ones(n)
    X = np.fft.rfft(x * w)
    amp = 2.0 * np.abs(X) / w.sum()
    amp[0] /= 2.0
    f = np.fft.rfftfreq(n, step)
    return Spectrum(f, amp, 1.0 / (n * step))


def windowed_spectra(t, x, t_start: float, window: float, count: int, **kw) -> list[Spectrum]:
    """Spectra of ``count`` consecutive windows of length ``window`` from t_start (Fig. 4-12:
    six 5-s windows of a discharge); windows past the end of the record are left out."""
    t = np.asarray(t, float)
    out = []
    for i in range(count):
        a = t_start + i * window
        if a + window > t[-1] + 1e-9 * window:
            break
        out.append(spectrum(t, x, t_start=a, t_end=a + window, **kw))
    return out


def averaged_spectrum(t, x, segments: int = 6, t_start: float | None = None, t_end: float | None = None) -> Spectrum:
    """Welch's average of the record cut into ``segments`` equal, half-overlapping Hann
    windows (2·segments − 1 of them), as amplitudes: a sine of amplitude A shows A. A wave
    that persists through the record (the fill's longitudinal mode, Fig. 4-12's peak in every
    window) stands out; a transient that one window happens to catch is averaged down. The
    resolution is that of one window, segments/T."""
    f, power = _welch_power(t, x, segments, t_start, t_end)
    return Spectrum(f, np.sqrt(2.0 * power), float(f[1]))


def _welch_power(t, x, segments, t_start, t_end, segment_samples: int | None = None):
    """(frequencies, Welch power per bin) of the record in [t_start, t_end], resampled uniformly,
    in half-overlapping Hann segments of ``segment_samples`` (default: the record over
    ``segments``), each linearly detrended."""
    from scipy import signal as sps

    t, x = _window(t, x, t_start, t_end, 8 * segments, "an averaged spectrum")
    tu = np.linspace(t[0], t[-1], t.size)
    fs = (t.size - 1) / (t[-1] - t[0])
    return sps.welch(np.interp(tu, t, x), fs=fs, window="hann", nperseg=segment_samples or t.size // segments,
                     detrend="linear", scaling="spectrum")


@dataclass
class EnsemblePeak:
    spectrum: Spectrum  # the realisations' mean Welch power, as amplitudes
    frequency: float  # its largest peak above min_frequency (Hz; NaN if none)
    interval: tuple[float, float]  # the peak's bootstrap interval over the realisations (Hz)
    each: np.ndarray  # every realisation's own Welch peak (Hz), as `averaged_spectrum` finds it


def ensemble_peak(records, segments: int = 6, min_frequency: float = LOW_CUTOFF, t_start: float | None = None,
                  t_end: float | None = None, level: float = 0.9, draws: int = 2000) -> EnsemblePeak:
    """The spectral peak of a chaotic signal from several realisations of it (the same run with
    an immaterial change, e.g. Δt × 0.99): ``records`` is a list of (t, x). One realisation's
    highest bin hops within a broad hump from run to run; the quantity its periodograms
    estimate is the power spectral density, and the mean of the realisations' Welch powers
    (segments of one common length: the shortest record over ``segments``) estimates it with
    1/N of one realisation's variance (N realisations). Its largest peak above
    ``min_frequency`` is the ensemble's; its ``level`` interval is the percentile bootstrap over the realisations
    (resampled with replacement ``draws`` times, seeded: reproducible)."""
    cut = [_window(t, x, t_start, t_end, 8 * segments, "an ensemble spectrum") for t, x in records]
    rate = min((tk.size - 1) / (tk[-1] - tk[0]) for tk, _ in cut)
    nseg = (int(round(min((tk[-1] - tk[0]) for tk, _ in cut) * rate)) + 1) // segments
    powers, each = [], []
    for tk, xk in cut:  # one sampling rate for all: the same frequency bins
        tu = np.arange(tk[0], tk[-1] + 0.5 / rate, 1.0 / rate)
        f, pk = _welch_power(tu, np.interp(tu, tk, xk), segments, None, None, nseg)
        powers.append(pk)
        one = Spectrum(f, np.sqrt(2.0 * pk), float(f[1])).peaks(1, min_frequency=min_frequency)
        each.append(float(one[0]) if one.size else np.nan)
    powers = np.array(powers)

    def peak(p):
        found = Spectrum(f, np.sqrt(2.0 * p), float(f[1])).peaks(1, min_frequency=min_frequency)
        return float(found[0]) if found.size else np.nan

    rng = np.random.default_rng(0)
    boot = np.array([peak(powers[rng.integers(0, len(powers), len(powers))].mean(axis=0)) for _ in range(draws)])
    lo, hi = np.nanpercentile(boot, [50 * (1 - level), 50 * (1 + level)])
    mean = powers.mean(axis=0)
    return EnsemblePeak(Spectrum(f, np.sqrt(2.0 * mean), float(f[1])), peak(mean), (float(lo), float(hi)),
                        np.array(each))


@dataclass
class ModeShape:
    ratio: np.ndarray  # complex: each signal's amplitude and phase relative to the reference's in the band
    coherence: np.ndarray  # γ² in [0, 1]: the share of each signal's band power that moves with the reference

    @property
    def in_phase(self) -> np.ndarray:
        """|ratio| cos(phase): the shape as a standing mode draws it (negative: against the reference)."""
        return self.ratio.real


def mode_shape(t, signals, band: tuple[float, float], reference: int = 0, segment: float = 1.0,
               t_start: float | None = None, t_end: float | None = None) -> ModeShape:
    """The shape of an oscillation that several signals (rows, sampled at the times ``t``)
    share in a frequency band: Welch's cross-spectra with the reference row (half-overlapping
    Hann segments of ``segment`` s, linear detrend), summed over the band's bins,
    H_k = Σ S_k,ref / Σ S_ref,ref - the transfer from the reference to signal k, whose
    magnitude is the amplitude relative to the reference and whose angle is the phase - and
    the coherence γ²_k = |Σ S_k,ref|² / (Σ S_k,k Σ S_ref,ref): 1 where signal k moves with the
    reference in the band (one mode), ~0 where it does not. An oscillation that drifts in
    frequency or amplitude within the band is measured whole; what lies outside it is not."""
    from scipy import signal as sps

    t, x = _window(t, np.atleast_2d(np.asarray(signals, float)).T, t_start, t_end, 8, "a mode shape")
    fs = (t.size - 1) / (t[-1] - t[0])
    nperseg = int(round(segment * fs))
    if nperseg < 8 or t.size < nperseg:
        raise ValueError(f"need at least one {segment} s segment of 8 samples or more for a mode shape")
    tu = np.linspace(t[0], t[-1], t.size)
    x = np.array([np.interp(tu, t, row) for row in x.T])
    kw = dict(fs=fs, window="hann", nperseg=nperseg, detrend="linear", axis=-1)
    f, power = sps.welch(x, **kw)
    inside = (f >= band[0]) & (f <= band[1])
    if not inside.any():
        raise ValueError(f"no frequency bin in the band {band} Hz (resolution {f[1]:.3g} Hz)")
    power = power[:, inside].sum(axis=1)
    cross = sps.csd(x[reference], x, **kw)[1][:, inside].sum(axis=1)  # conj(X_ref) X_k
    p_ref = power[reference]
    return ModeShape(cross / p_ref, np.abs(cross) ** 2 / np.maximum(power * p_ref, np.finfo(float).tiny))


@dataclass
class TravellingWave:
    speed: float  # m/s, its phase speed along the axis of the positions (+: towards larger ones)
    growth: float  # 1/m: d ln|amplitude| / dx along that axis (+: it grows towards larger x)
    phase_residual: float  # rad: rms of the phase about the fitted line (a standing wave's is large)


def travelling_wave(x, ratio, frequency: float) -> TravellingWave:
    """A wave at one frequency from its complex amplitudes at positions x (a
    :class:`ModeShape`'s ratio along a line): the phase, unwrapped in order of x, fitted by a
    line, arg H = φ0 − k x, gives the phase speed 2π f/k (positive towards larger x), and
    ln|H| = c + g x the growth rate g. A travelling wave leaves a phase residual of a few
    degrees; a standing one, whose phase jumps by π at its nodes, leaves tens."""
    x = np.asarray(x, float)
    order = np.argsort(x)
    x, h = x[order], np.asarray(ratio, complex)[order]
    if x.size < 3:
        raise ValueError("need the wave at three positions or more")
    phase = np.unwrap(np.angle(h))
    slope, phi0 = np.polyfit(x, phase, 1)
    growth = np.polyfit(x, np.log(np.abs(h)), 1)[0]
    residual = float(np.sqrt(np.mean((phase - (phi0 + slope * x)) ** 2)))
    return TravellingWave(-2.0 * np.pi * frequency / slope if slope != 0 else np.inf, float(growth), residual)


def low_frequency_fluctuation(t, x, t_start: float | None = None, t_end: float | None = None,
                              cutoff: float = LOW_CUTOFF) -> tuple[float, float]:
    """(RMS, dominant frequency in Hz) of the part of a history below ``cutoff``.

    The window [t_start, t_end] is resampled uniformly, its mean and linear trend removed (over
    a whole discharge the pressure drains: a trend, not a fluctuation), and the result
    low-pass filtered by a 4th-order Butterworth filter run forwards and backwards (zero
    phase: |H|² = 1/(1 + (f/f_c)⁸), −6 dB at the cutoff; 0.5 Hz passes at 0.996, 0.7 Hz at
    0.946, a 5 Hz wave under a 1 Hz cutoff is attenuated by ~10⁻⁵·⁶). The RMS is of the filtered signal away from the record's
    ends (1/cutoff s at each end are left out where the record is long enough: the filter's
    end effects live there); the dominant frequency is the largest peak of its Hann spectrum
    above one bin (resolution 1/T: a window of T seconds resolves nothing slower than 1/T)."""
    tu, _, low, inside = _split_low(t, x, t_start, t_end, cutoff)
    s = spectrum(tu, low, detrend="constant")
    peaks = s.peaks(1, min_frequency=s.resolution)
    return float(np.sqrt(np.mean(low[inside] ** 2))), float(peaks[0]) if peaks.size else float("nan")


THESIS_WINDOW = 10.0  # s: Fig. 4-12 cuts the 60-s record at point e into six consecutive windows


def windowed_low_fluctuation(t, x, t_start: float | None = None, t_end: float | None = None,
                             window: float = THESIS_WINDOW, cutoff: float = LOW_CUTOFF) -> float:
    """RMS of the part of a history below ``cutoff`` within consecutive windows of about
    ``window`` seconds, each measured as :func:`low_frequency_fluctuation` measures a record
    (its own mean and linear trend removed, the same zero-phase filter, the same trim of the
    filter's end effects), the squares pooled over the windows. This is what the thesis'
    windowed spectra (Fig. 4-12) can see: nothing slower than one window. A drift over the
    whole record that a single linear trend does not remove - a station's pressure recovering
    over tens of seconds after its switch to the flowing state, as in a slow controlled
    discharge - counts in :func:`low_frequency_fluctuation` and not here."""
    t, x = _window(t, x, t_start, t_end, 16, "the windowed low-frequency fluctuation")
    n = max(1, int(round((t[-1] - t[0]) / window)))
    edges = t[0] + (t[-1] - t[0]) * np.arange(n + 1) / n
    squares, count = 0.0, 0
    for a, b in zip(edges[:-1], edges[1:]):
        _, _, low, inside = _split_low(t, x, a, b, cutoff)
        squares += float(np.sum(low[inside] ** 2))
        count += int(inside.sum())
    return float(np.sqrt(squares / count))


def fast_fluctuation(t, x, t_start: float | None = None, t_end: float | None = None,
                     cutoff: float = LOW_CUTOFF) -> float:
    """RMS of the part of a history above ``cutoff``: the detrended signal minus the part
    :func:`low_frequency_fluctuation` measures, over the same interior window."""
    _, xu, low, inside = _split_low(t, x, t_start, t_end, cutoff)
    return float(np.sqrt(np.mean((xu - low)[inside] ** 2)))


def low_pass(t_uniform, x, cutoff: float = LOW_CUTOFF) -> np.ndarray:
    """The part of a uniformly sampled signal below ``cutoff``: 4th-order Butterworth run
    forwards and backwards (zero phase, |H|² = 1/(1 + (f/f_c)⁸)), padded over 3/cutoff s."""
    from scipy import signal as sps

    t_uniform = np.asarray(t_uniform, float)
    fs = (t_uniform.size - 1) / (t_uniform[-1] - t_uniform[0])
    sos = sps.butter(4, cutoff, btype="low", fs=fs, output="sos")
    return sps.sosfiltfilt(sos, x, padlen=min(t_uniform.size - 1, int(3 * fs / cutoff)))


def _split_low(t, x, t_start, t_end, cutoff):
    """(uniform times, detrended signal, its part below cutoff, the samples away from the
    filter's end effects)."""
    from scipy import signal as sps

    t, x = _window(t, x, t_start, t_end, 16, "the low-frequency fluctuation")
    tu = np.linspace(t[0], t[-1], t.size)
    xu = sps.detrend(np.interp(tu, t, x), type="linear")
    low = low_pass(tu, xu, cutoff)
    # the filter's end effects (a record does not end on a period of its faster waves) reach
    # about 1/cutoff into it: the RMS is taken inside, where they have died out
    inside = (tu >= tu[0] + 1.0 / cutoff) & (tu <= tu[-1] - 1.0 / cutoff)
    if inside.sum() < t.size // 2:
        inside[:] = True
    return tu, xu, low, inside


@dataclass
class PulseTravel:
    """How the wall-pressure pulses above ``cutoff`` travel along the wall (:func:`pulse_travel`)."""

    s_low: np.ndarray  # wall distance of each pair's lower station (m)
    s_high: np.ndarray  # and of its upper one
    lag: np.ndarray  # s: the upper station's pulses lag the lower one's by this (negative: they lead)
    correlation: np.ndarray  # the normalised cross-correlation at that lag
    frequency: float  # Hz: the pulses' dominant frequency (the stations' pooled spectrum above cutoff)
    max_lag: float  # s: the lags searched, ± half a period of that frequency
    min_correlation: float  # pairs at or above this carry the speed

    @property
    def tracked(self) -> np.ndarray:
        return self.correlation >= self.min_correlation

    @property
    def speed(self) -> float:
        """The pulses' speed along the wall (m/s, positive up it) over the tracked pairs: the
        inverse of their median slowness lag/Δs (a pair in phase counts as slowness 0: a speed
        beyond what the sampling resolves, inf); NaN when no pair is tracked."""
        if not np.any(self.tracked):
            return float("nan")
        slowness = float(np.median(self.lag[self.tracked] / (self.s_high - self.s_low)[self.tracked]))
        return float("inf") if slowness == 0.0 else 1.0 / slowness


def pulse_travel(t, s, p, cutoff: float = LOW_CUTOFF, min_correlation: float = 0.5) -> PulseTravel:
    """Whether and how fast the wall pressure's pulses above ``cutoff`` run along the wall.

    ``t`` (n_t) uniform sample times, ``s`` (n) the stations' distances along the wall, ``p``
    (n, n_t) their histories. Each history is detrended (linear) and its part below ``cutoff``
    removed (the zero-phase filter of :func:`low_pass`); the pulses' dominant frequency f is the
    peak of the stations' pooled Hann spectrum above ``cutoff``. For each pair of neighbouring
    stations (sorted by s) the lag that maximises their normalised cross-correlation is searched
    within ± 1/(2f) - half a period: a periodic train correlates again a period on, so a longer
    search could not tell a wave running up from one running down - and refined between samples
    by a parabola through the peak. A wave travelling up the wall at speed c shows as lags Δs/c
    with a correlation near 1; a pulse felt everywhere at once (the whole fill moving as one, a
    standing mode) as lags near 0; pulses that are local (slip-stick of one stretch of wall)
    as correlations well below 1."""
    t = np.asarray(t, float)
    s = np.asarray(s, float)
    p = np.asarray(p, float)
    if p.ndim != 2 or p.shape != (s.size, t.size) or s.size < 2 or t.size < 16:
        raise ValueError(f"p: expected (stations, samples) = ({s.size}, {t.size}) with ≥ 2 stations and ≥ 16 "
                         f"samples, got {p.shape}")
    from scipy import signal as sps

    order = np.argsort(s)
    s, p = s[order], p[order]
    dt = (t[-1] - t[0]) / (t.size - 1)
    x = sps.detrend(p, axis=1, type="linear")
    x = np.array([row - low_pass(t, row, cutoff) for row in x])
    f = np.fft.rfftfreq(t.size, dt)
    power = np.sum(np.abs(np.fft.rfft(x * np.hanning(t.size), axis=1)) ** 2, axis=0)
    above = f > cutoff
    frequency = float(f[above][np.argmax(power[above])]) if np.any(above) else float("nan")
    max_lag = 0.5 / frequency
    m = max(1, int(max_lag / dt))
    lags, corr = np.zeros(s.size - 1), np.zeros(s.size - 1)
    for i in range(s.size - 1):
        c = _cross_correlation(x[i], x[i + 1], m)
        if c is None:
            lags[i], corr[i] = np.nan, 0.0
            continue
        j = int(np.argmax(c))
        shift = 0.0
        if 0 < j < c.size - 1:
            den = c[j - 1] - 2 * c[j] + c[j + 1]
            shift = 0.5 * (c[j - 1] - c[j + 1]) / den if den != 0 else 0.0
        lags[i], corr[i] = (j - m + shift) * dt, c[j]
    return PulseTravel(s[:-1], s[1:], lags, corr, frequency, max_lag, min_correlation)


def _cross_correlation(a, b, m: int) -> np.ndarray | None:
    """Σ a(i) b(i + k) / √(Σa² Σb²) for the lags k = −m … m samples (b following a by k shows at
    +k); None if either signal is zero."""
    norm = np.sqrt(np.sum(a * a) * np.sum(b * b))
    if norm == 0.0:
        return None
    return np.array([np.sum(a[: a.size - k] * b[k:]) if k >= 0 else np.sum(a[-k:] * b[: b.size + k])
                     for k in range(-m, m + 1)]) / norm


def slow_part(t, x, cutoff: float = LOW_CUTOFF) -> tuple[np.ndarray, np.ndarray]:
    """(times, values) of the part of a history below ``cutoff`` as
    :func:`low_frequency_fluctuation` takes it (resampled uniformly, mean and linear trend
    removed, the zero-phase filter), away from the filter's end effects and thinned to eight
    samples per period of the cutoff (it holds nothing faster)."""
    tu, _, low, inside = _split_low(t, x, None, None, cutoff)
    step = max(1, int(round((tu.size - 1) / (tu[-1] - tu[0]) / (8.0 * cutoff))))
    return tu[inside][::step], low[inside][::step]


def best_lag(a, b, m: int) -> tuple[int, float]:
    """(k, r): the lag k within ± m samples (b following a by k: k > 0) where the normalised
    cross-correlation of two signals is largest in magnitude, and its value (signed); (0, NaN)
    if either is zero."""
    c = _cross_correlation(a, b, min(m, a.size // 2))
    if c is None:
        return 0, float("nan")
    j = int(np.argmax(np.abs(c)))
    return j - (c.size - 1) // 2, float(c[j])


def low_correlation(t, a, b, max_lag: float = 1.0, cutoff: float = LOW_CUTOFF) -> tuple[float, float]:
    """(lag in s, r): how the parts below ``cutoff`` (:func:`slow_part`) of two histories sampled
    at the times ``t`` follow each other - their normalised cross-correlation r at the lag within
    ± ``max_lag`` where |r| is largest (a positive lag: b follows a; r < 0: one falls as the
    other rises), to the thinned sampling's 1/(8 cutoff) s. (0, NaN) if either has no slow part."""
    ts, slow_a = slow_part(t, a, cutoff)
    slow_b = slow_part(t, b, cutoff)[1]
    dt = (ts[-1] - ts[0]) / (ts.size - 1)
    k, r = best_lag(slow_a, slow_b, max(1, int(round(max_lag / dt))))
    return k * dt, r


def chance_correlation(a, rows, m: int, shifts: int = 40, seed: int = 0, level: float = 0.95) -> float:
    """How large the best |r| of :func:`best_lag` between ``a`` and any of ``rows`` (each the same
    length, lags ± m samples) comes out by chance: its ``level`` quantile over ``shifts`` circular
    shifts of ``a`` by random offsets of at least a tenth of the record (what the search finds
    in two slow signals that have nothing to do with each other: few independent samples and
    many rows inflate it)."""
    rng = np.random.default_rng(seed)
    n = a.size
    best = []
    for shift in rng.integers(max(1, n // 10), n - max(1, n // 10), size=shifts):
        shifted = np.roll(a, int(shift))
        best.append(max((abs(r) for r in (best_lag(shifted, row, m)[1] for row in rows) if np.isfinite(r)),
                        default=0.0))
    return float(np.quantile(best, level))


FRONT_ONSET = 0.1  # a band has failed once a tenth of its loaded solid is at yield: the bands above the front
#                   are elastic (0 exactly), those it has passed flicker around 0.1-0.6 (the ch. 4 runs)


def failure_front(t, z, shares, onset: float = FRONT_ONSET) -> tuple[np.ndarray, np.ndarray, int]:
    """How a failure climbs through height bands (centres ``z``; ``shares`` (bands, samples):
    each band's share at yield at the times ``t``): (times, heights) at which the front passes
    the bands that were below ``onset`` at t[0] - a band is passed once it and every such band
    below it have reached it (:func:`first_time_reaching`); the front stops below the first
    that never does (a band above it that fails early, a free surface flickering, is not
    passed) - and how many bands were below ``onset`` at t[0]. Bands without a record at t[0]
    (NaN: empty) are left out."""
    shares, z = np.asarray(shares, float), np.asarray(z, float)
    fresh = np.nonzero(np.isfinite(shares[:, 0]) & (shares[:, 0] < onset))[0]
    fresh = fresh[np.argsort(z[fresh])]
    arrival = np.array([first_time_reaching(t, np.nan_to_num(shares[k]), onset) for k in fresh])
    passed = np.cumprod(np.isfinite(arrival)).astype(bool)
    return np.maximum.accumulate(arrival[passed]), z[fresh][passed], int(fresh.size)


def front_speed(t, z) -> float:
    """The speed (m/s, positive up) of a front passing the heights ``z`` at the times ``t``:
    the inverse of the least-squares slope dt/dz (inf where the heights fail at once)."""
    if np.ptp(np.asarray(t, float)) == 0.0:
        return float("inf")
    return float(1.0 / np.polyfit(np.asarray(z, float), np.asarray(t, float), 1)[0])


def front_growth(t, height, late: float = 0.05) -> tuple[float, float]:
    """How a front's height above where it started grows with time: (the exponent n of
    height ∝ tⁿ, a log-log least-squares line; ½ for a diffusing front, 1 for one at a constant
    speed, and the coefficient height²/t of a diffusing one, least squares through the
    origin), over the arrivals after ``late`` of the last (the first instants at the source
    are not the front's growth). NaNs with fewer than three such arrivals or all of them at
    once (no growth to fit)."""
    t, height = np.asarray(t, float), np.asarray(height, float)
    keep = (t >= late * t.max()) & (t > 0.0) & (height > 0.0)
    if keep.sum() < 3 or np.ptp(t[keep]) == 0.0:
        return float("nan"), float("nan")
    exponent = np.polyfit(np.log(t[keep]), np.log(height[keep]), 1)[0]
    return float(exponent), float(np.sum(height[keep] ** 2 * t[keep]) / np.sum(t[keep] ** 2))


@dataclass
class EventSteps:
    step: np.ndarray  # the mean over `window` after each event minus the mean over `window` before it
    exceedance: np.ndarray  # the share of the instants away from every event whose |step| is at least as large
    typical: float  # the median |step| at those instants


def event_steps(t, x, events, window: float, t_start: float, t_end: float) -> EventSteps:
    """Whether a record steps at given instants (a re-mesh, a stage change) more than it steps
    anyway: the step at each event, mean over (e, e + window] minus mean over [e − window, e),
    against the same statistic at every instant of a grid (spacing window/4) in
    [t_start + window, t_end − window] at least 2·window from every event - as an empirical
    exceedance: 0.01 means one instant in a hundred steps as much without an event. A pulsing
    record steps by its pulses' size; only an event whose exceedance is small stepped it.
    Events within ``window`` of either end get NaN."""
    t, x = np.asarray(t, float), np.asarray(x, float)
    events = np.asarray(events, float)

    def step(e):
        before, after = (t >= e - window) & (t < e), (t > e) & (t <= e + window)
        return x[after].mean() - x[before].mean() if before.any() and after.any() else np.nan

    grid = np.arange(t_start + window, t_end - window, 0.25 * window)
    if events.size:
        grid = grid[np.min(np.abs(grid[:, None] - events[None, :]), axis=1) >= 2.0 * window]
    quiet = np.abs(np.array([step(e) for e in grid]))
    quiet = quiet[np.isfinite(quiet)]
    steps = np.array([step(e) if t_start + window <= e <= t_end - window else np.nan for e in events])
    exceed = np.array([np.mean(quiet >= abs(s)) if np.isfinite(s) and quiet.size else np.nan for s in steps])
    return EventSteps(steps, exceed, float(np.median(quiet)) if quiet.size else np.nan)


def switch_time(t, p, t_open: float, cutoff: float = LOW_CUTOFF) -> float:
    """When a station's wall pressure has switched from the filled state to the flowing one: the
    first time after ``t_open`` that its part below ``cutoff`` (zero-phase 4th-order
    Butterworth, as :func:`low_frequency_fluctuation`) crosses halfway from its value at the
    opening to its median over the record's second half (up or down: high on the wall the flow
    raises it). A free discharge switches within a second; a slowly controlled one later, the
    slower the later (the outlet must move the solid before the stress state changes). NaN if it
    never crosses."""
    t, p = _window(t, p, t_open, None, 16, "the switch time")
    tu = np.linspace(t[0], t[-1], t.size)
    low = low_pass(tu, np.interp(tu, t, p), cutoff)
    start, late = p[0], float(np.median(p[t >= 0.5 * (t[0] + t[-1])]))
    half = 0.5 * (start + late)
    crossed = np.nonzero(np.sign(low - half) == np.sign(late - half))[0]
    return float(tu[crossed[0]]) if crossed.size and late != start else float("nan")


def mobilised_friction(p_n, p_s, p_min: float = 1.0) -> np.ndarray:
    """|p_s| / p_n where the wall is loaded (p_n > p_min Pa), NaN elsewhere (Figs. 4-13/4-14)."""
    p_n = np.asarray(p_n, float)
    p_s = np.asarray(p_s, float)
    out = np.full(p_n.shape, np.nan)
    on = p_n > p_min
    out[on] = np.abs(p_s[on]) / p_n[on]
    return out


def slip_fraction(slip_velocity, threshold: float = 1e-4) -> float:
    """Fraction of the samples in which the wall node slides (|v_slip| > threshold m/s)."""
    v = np.abs(np.asarray(slip_velocity, float))
    return float(np.mean(v > threshold)) if v.size else float("nan")


def station_means(history: dict, t_start: float, t_end: float, column: str = "p_n") -> tuple[np.ndarray, np.ndarray]:
    """(mean height, time-averaged ``column``) of every wall station over [t_start, t_end]
    (eq. 4-9), from a wall_history.csv read by :func:`silo_dolfinx.output.read_csv`; stations
    in index order."""
    st = np.asarray(history["station"], float)
    z, v = [], []
    for k in np.unique(st):
        m = st == k
        z.append(time_average(history["t"][m], history["z"][m], t_start, t_end))
        v.append(time_average(history["t"][m], history[column][m], t_start, t_end))
    return np.array(z), np.array(v)


def wall_mean(s, p, s_centre: float, half_width: float) -> float:
    """Mean of a nodal wall profile p(s) over the arclength [s_centre − w, s_centre + w],
    linear between nodes (as a Q1 trace is). At a corner of the wall the nodal value grows
    without bound as the mesh is refined (the stress is singular there); the mean over a
    fixed length, what the wall carries there, converges."""
    s, p = np.asarray(s, float), np.asarray(p, float)
    o = np.argsort(s)
    s, p = s[o], p[o]
    a, b = s_centre - half_width, s_centre + half_width
    if half_width <= 0 or a < s[0] - 1e-12 or b > s[-1] + 1e-12:
        raise ValueError(f"the window [{a:g}, {b:g}] m must lie within the profile's [{s[0]:g}, {s[-1]:g}] m")
    inside = (s > a) & (s < b)
    ss = np.concatenate(([a], s[inside], [b]))
    return float(np.trapezoid(np.interp(ss, s, p), ss) / (b - a))


def profile_at(z, z_profile, p_profile) -> np.ndarray:
    """A wall profile p(z) (a wall_profile_<stage>.csv column, in wall order) interpolated
    linearly at heights z."""
    order = np.argsort(z_profile)
    return np.interp(np.asarray(z, float), np.asarray(z_profile, float)[order], np.asarray(p_profile, float)[order])


def overpressure(z, p_discharge, z_fill, p_fill) -> np.ndarray:
    """Discharge over filling pressure at heights z: the discharge mean divided by the
    end-of-fill profile interpolated there (NaN where the fill pressure is ~0)."""
    pf = profile_at(z, z_fill, p_fill)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(pf > 1e-9 * np.max(np.abs(pf)), np.asarray(p_discharge, float) / pf, np.nan)


def representative_deviation(values, reference, normaliser=None) -> float:
    """S0 = √(mean(((P − P0)/N)²)): eq. 3-13 with N = P0 (pointwise); eq. 5-18 with N = σ⁺0
    (a scalar) and P0 the predicted disturbance."""
    v = np.asarray(values, float)
    r = np.asarray(reference, float)
    nrm = r if normaliser is None else np.asarray(normaliser, float)
    return float(np.sqrt(np.mean(((v - r) / nrm) ** 2)))


def discharged_volume_percentage(initial_volume: float, volume) -> np.ndarray:
    """Eq. 6-2: V_dis = (V0 − V')/V0 × 100 %."""
    if initial_volume <= 0:
        raise ValueError("initial_volume must be positive")
    return (initial_volume - np.asarray(volume, float)) / initial_volume * 100.0


def discharged_percentage(discharged_mass, mass_at_opening: float) -> np.ndarray:
    """Eq. 6-2 counted in mass: V_dis = (V0 − V')/V0 × 100 % with V0, V' the solid's volumes at
    its density at the opening — the discharged mass over the mass at the opening."""
    if mass_at_opening <= 0:
        raise ValueError("mass_at_opening must be positive")
    return np.asarray(discharged_mass, float) / mass_at_opening * 100.0


def first_time_reaching(t, series, level: float) -> float:
    """The first time a non-decreasing-on-the-whole ``series`` reaches ``level`` (linear
    interpolation between samples); nan if it never does."""
    t, y = np.asarray(t, float), np.asarray(series, float)
    i = np.nonzero(y >= level)[0]
    if i.size == 0:
        return float("nan")
    j = int(i[0])
    if j == 0 or y[j] == y[j - 1]:
        return float(t[j])
    return float(t[j - 1] + (level - y[j - 1]) * (t[j] - t[j - 1]) / (y[j] - y[j - 1]))


def steady_flow_start(t, discharged_mass, window: float = 1.0, tolerance: float = 0.1,
                      t_start: float | None = None) -> float:
    """When the discharge becomes steady: the start of the first window (of ``window`` s, from
    ``t_start``) from which the mass flow of every later whole window (three at least) stays
    within ``tolerance`` of their mean, and their linear trend changes it by less than that
    over their span (a slow drift is not steady). nan if there is no such window."""
    starts, rates = windowed_mass_flow(t, discharged_mass, window, t_start)
    for i in range(starts.size - 2):
        rest = rates[i:]
        mean = rest.mean()
        if mean <= 0 or np.any(np.abs(rest - mean) > tolerance * mean):
            continue
        slope = np.polyfit(starts[i:], rest, 1)[0]
        if abs(slope) * (starts[-1] - starts[i]) <= tolerance * mean:
            return float(starts[i])
    return float("nan")


def outlet_mass_flow(r, vz, density) -> float:
    """Mass flow rate (kg/s) through a horizontal outlet: ∫ ρ (−v_z) 2π r dr (trapezoid over
    the outlet nodes sorted by r; downward velocity negative)."""
    r = np.asarray(r, float)
    o = np.argsort(r)
    r, vz = r[o], np.asarray(vz, float)[o]
    rho = np.broadcast_to(np.asarray(density, float), r.shape)[o] if np.ndim(density) else density
    return float(np.trapezoid(rho * (-vz) * 2.0 * np.pi * r, r))


def flow_rate_from_mass(t, discharged_mass):
    """W(t) = dM/dt by central differences (kg/s)."""
    return np.gradient(np.asarray(discharged_mass, float), np.asarray(t, float))


def janssen_comparison(z, p_n, p_s, *, fill_height: float, radius: float, mu: float, k: float,
                       unit_weight: float, z_min: float, z_max: float | None = None, slip_tol: float = 0.01):
    """A vertical wall's filling pressures against Janssen (theory.janssen with K = ``k``) from
    one Janssen depth z0 = R/(2Kμ) below the surface down to ``z_min`` (or between z_min and
    z_max if given): dict with the window, the ratio p_n/p_Janssen at each node in it (and its
    range), and the fraction of those nodes at the friction limit |p_s/p_n − μ| ≤ slip_tol μ
    (the wall slides there)."""
    from silo_dolfinx import theory

    z, p_n, p_s = (np.asarray(a, float) for a in (z, p_n, p_s))
    z0 = theory.janssen_depth(radius, mu, k)
    top = fill_height - z0 if z_max is None else z_max
    sel = (z >= z_min) & (z <= top) & (p_n > 0)
    ph, _, _ = theory.janssen(fill_height - z[sel], radius, mu, k, unit_weight)
    ratio = p_n[sel] / ph
    at_limit = np.abs(p_s[sel] / p_n[sel] - mu) <= slip_tol * mu
    return {"z0": z0, "window": (z_min, top), "z": z[sel], "ratio": ratio,
            "ratio_min": float(ratio.min()) if ratio.size else np.nan,
            "ratio_max": float(ratio.max()) if ratio.size else np.nan,
            "slip_fraction": float(at_limit.mean()) if at_limit.size else np.nan,
            "mobilised_mean": float(np.mean(p_s[sel] / p_n[sel])) if ratio.size else np.nan}


@dataclass(frozen=True)
class JanssenFit:
    """Janssen's curve fitted to a vertical wall's normal pressures: the rate and the level."""

    k: float  # lateral pressure ratio
    mu: float  # wall friction the fill mobilises
    z0: float  # Janssen depth R/(2 μ K) (m): how fast the asymptote is approached
    p_inf: float  # asymptote γR/(2μ) (Pa): the level
    rms: float  # RMS residual of the fit (Pa)


def janssen_fit(z, p_n, *, fill_height: float, radius: float, unit_weight: float, z_min: float,
                z_max: float | None = None) -> JanssenFit:
    """Least-squares fit of theory.janssen's p_h(depth; K, μ) to wall pressures p_n(z) between
    z_min and z_max (default the fill height), both K and μ free. Janssen's p_h = p_inf (1 −
    exp(−depth/z0)) separates what a fill's K and its wall friction do: the depth scale z0 and
    the level p_inf (thesis Fig. 7-5: "the internal friction angle governs the lateral pressure
    ratio, which determines how rapid the pressure can achieve the asymptotic Janssen pressure")."""
    from scipy.optimize import least_squares

    from silo_dolfinx import theory

    z, p_n = np.asarray(z, float), np.asarray(p_n, float)
    sel = (z >= z_min) & (z <= (fill_height if z_max is None else z_max))
    if np.count_nonzero(sel) < 3:
        raise ValueError(f"janssen_fit needs at least three pressures between z {z_min:g} and the top; "
                         f"got {np.count_nonzero(sel)}")
    depth, p = fill_height - z[sel], p_n[sel]

    def residual(x):
        return theory.janssen(depth, radius, x[1], x[0], unit_weight)[0] - p

    fit = least_squares(residual, [0.4, 0.5], bounds=([1e-3, 1e-3], [10.0, 10.0]), x_scale=[0.1, 0.1])
    k, mu = (float(v) for v in fit.x)
    return JanssenFit(k=k, mu=mu, z0=theory.janssen_depth(radius, mu, k), p_inf=unit_weight * radius / (2 * mu),
                      rms=float(np.sqrt(np.mean(fit.fun ** 2))))


def windowed_mass_flow(t, discharged_mass, window: float, t_start: float | None = None):
    """The mass actually leaving in consecutive windows of ``window`` s from ``t_start``
    (default: the first sample): (window start times, mean flow rate = mass discharged in the
    window / its length, kg/s). Only whole windows; the discharged mass is interpolated
    linearly at the window edges, so the sampling need not be uniform."""
    t = np.asarray(t, float)
    m = np.asarray(discharged_mass, float)
    if window <= 0:
        raise ValueError("window must be positive")
    t0 = t[0] if t_start is None else float(t_start)
    n = int(np.floor((t[-1] - t0) / window + 1e-9))
    edges = t0 + window * np.arange(n + 1)
    mass = np.interp(edges, t, m)
    return edges[:-1], np.diff(mass) / window


# ---------------------------------------------------------------------------- flow pattern
def flow_channel_boundary(r, z, vz, fraction: float = 1e-3, rows: np.ndarray | None = None):
    """Ch. 6.4.3: at each height, the radius where |v_z| first falls below ``fraction`` of the
    centreline |v_z| at that height (linear interpolation between samples along r).

    r, z, vz: 2-D arrays (heights × radii, radii increasing, the first column on the axis) or
    1-D scattered points with ``rows`` the height of each row. Returns (z_rows, r_fcb) with
    r_fcb = nan where the whole row flows (mass flow at that height)."""
    r, z, vz = (np.asarray(a, float) for a in (r, z, vz))
    if r.ndim == 1:
        zs = np.unique(z) if rows is None else np.asarray(rows, float)
        R, Z, VZ = [], [], []
        for zi in zs:
            sel = np.isclose(z, zi)
            o = np.argsort(r[sel])
            R.append(r[sel][o])
            VZ.append(vz[sel][o])
            Z.append(zi)
        out = [_fcb_row(ri, vi, fraction) for ri, vi in zip(R, VZ)]
        return np.array(Z), np.array(out)
    out = np.array([_fcb_row(r[i], vz[i], fraction) for i in range(r.shape[0])])
    return z[:, 0], out


def flow_channel_from_nodes(xy, vz, radius_at, fraction: float = 1e-3, rows: int = 60, columns: int = 101):
    """The flow-channel boundary of a nodal velocity field (a snapshot's node_xy and v_z):
    v_z interpolated (linear; nearest outside the hull) onto ``rows`` heights between 2 % and
    98 % of the top and ``columns`` radii from the axis to the wall, ``radius_at(z)`` the wall
    radius. Returns (z_rows, r_fcb, wall radius) as :func:`flow_channel_boundary`."""
    from scipy.interpolate import griddata

    xy = np.asarray(xy, float)
    zs = np.linspace(0.02 * xy[:, 1].max(), 0.98 * xy[:, 1].max(), rows)
    rw = np.asarray(radius_at(zs), float)
    R = rw[:, None] * np.linspace(0.0, 1.0, columns)[None, :]
    Z = np.repeat(zs[:, None], columns, axis=1)
    VZ = griddata(xy, vz, (R, Z), method="linear")
    VZ = np.where(np.isnan(VZ), griddata(xy, vz, (R, Z), method="nearest"), VZ)
    z_rows, r_fcb = flow_channel_boundary(R, Z, VZ, fraction)
    return z_rows, r_fcb, rw


def _fcb_row(r, vz, fraction):
    a = np.abs(vz)
    thresh = fraction * a[0]
    if a[0] == 0:
        return np.nan
    below = np.nonzero(a < thresh)[0]
    if below.size == 0:
        return np.nan
    j = below[0]
    if j == 0:
        return r[0]
    # linear interpolation between samples j-1 (above) and j (below)
    return float(r[j - 1] + (thresh - a[j - 1]) * (r[j] - r[j - 1]) / (a[j] - a[j - 1]))


def effective_transition(z_rows, r_fcb, wall_radius, tolerance: float = 0.0):
    """Height where the flow channel boundary meets the wall (the lowest row that flows to the
    wall: r_fcb = nan, or within ``tolerance`` of the wall radius there); nan if none.

    ``tolerance`` (m): the resolution of the boundary - one element. A wall that sticks holds
    its nodes at v_z = 0, so even a channel that flows right up to the wall has its 0.001
    boundary inside the last cell before it."""
    z_rows = np.asarray(z_rows, float)
    reach = np.isnan(r_fcb) | (np.asarray(r_fcb) >= np.asarray(wall_radius) * (1 - 1e-9) - tolerance)
    return float(z_rows[reach].min()) if np.any(reach) else float("nan")


def time_averaged_velocity(snapshots) -> tuple[np.ndarray, np.ndarray]:
    """(node positions of the last, node velocity averaged over all on its mesh) of field
    snapshot files (``fields/snapshot_*.npz`` of one run, in time order). One snapshot of a
    silo in discharge carries its stress waves - the slowly creeping parts of the section
    move up and down with them - so a flow-channel boundary drawn from one is ragged; the mean
    over a few seconds is the flow. A rezoned run's snapshots before its last rezone (their
    ``mesh`` number differs from the last one's) have other nodes: they are left out."""
    files = list(snapshots)
    if not files:
        raise ValueError("time_averaged_velocity: no snapshots")
    last = np.load(files[-1])
    mesh = int(last["mesh"]) if "mesh" in last else 0
    vs = [s["node_velocity"] for s in map(np.load, files) if (int(s["mesh"]) if "mesh" in s else 0) == mesh]
    return np.asarray(last["node_xy"], float), np.mean(np.asarray(vs, float), axis=0)


def windowed_transitions(snapshots, window: float, radius_at, t_start: float, tolerance: float = 0.0,
                         fraction: float = 1e-3):
    """The effective transition of consecutive windows of a discharge: v_z averaged over the
    snapshots of each window (:func:`time_averaged_velocity`), its flow-channel boundary
    (:func:`flow_channel_from_nodes`, criterion ``fraction``) and the height where it meets
    the wall (:func:`effective_transition`, within ``tolerance``). The windows (e − window, e]
    end at the last snapshot and step back by ``window`` while they lie after ``t_start``;
    one with fewer than two snapshots (a single one carries the stress waves) is left out.

    ``snapshots``: (t, file) in time order. Returns (window ends, transitions; nan where the
    boundary does not meet the wall), oldest first. A criterion read from one window is one
    sample of a quantity that wanders as the flow channel does: the spread over the windows
    of one run is its resolution."""
    snaps = list(snapshots)
    if not snaps:
        return np.zeros(0), np.zeros(0)
    t = np.array([s[0] for s in snaps], float)
    ends, heights = [], []
    e = t[-1]
    while e - window >= t_start - 1e-9:
        inside = [f for tt, f in snaps if e - window < tt <= e + 1e-9]
        if len(inside) >= 2:
            xy, v = time_averaged_velocity(inside)
            z_rows, r_fcb, rw = flow_channel_from_nodes(xy, v[:, 1], radius_at, fraction)
            ends.append(e)
            heights.append(effective_transition(z_rows, r_fcb, rw, tolerance))
        e -= window
    return np.array(ends[::-1]), np.array(heights[::-1])


def finite_spread(values) -> tuple[float, float, float, int]:
    """(median, min, max, count) of the finite values (nan where none is): the spread of a
    quantity read once per window, some windows giving none (:func:`windowed_transitions`)."""
    x = np.asarray(values, float)
    x = x[np.isfinite(x)]
    if not x.size:
        return float("nan"), float("nan"), float("nan"), 0
    return float(np.median(x)), float(x.min()), float(x.max()), int(x.size)


# ---------------------------------------------------------------------------- stress measures
def invariants(sig):
    """(p, q) of (n, 4) stresses: p = −tr σ/3 (compression +), q = √(3 J2)."""
    return p_q(sig)


def stress_ratio(sig, p_min: float = 0.0):
    """q/p (eq. 4-11) of (n, 4) stresses; NaN where p ≤ p_min (stress-free:
    :func:`silo_dolfinx.invariants.stress_ratio`)."""
    p, q = invariants(sig)
    return _ratio(p, q, p_min)


def mobilised_friction_angle(sig):
    """(φ_mob in degrees, b) of (n, 4) stresses (rr, zz, θθ, rz; tension +): the Mohr–Coulomb
    angle the stress mobilises, sin φ_mob = (σ1 − σ3)/(σ1 + σ3) with σ1 ≥ σ2 ≥ σ3 the principal
    pressures (compression +), and where the intermediate one lies, b = (σ2 − σ3)/(σ1 − σ3): 0 in
    axisymmetric compression (σ2 = σ3), 1 in extension (σ2 = σ1). A cohesionless solid is at
    yield where φ_mob reaches its strength at that b: φ itself on Mohr–Coulomb's pyramid, between
    the two angles :func:`silo_dolfinx.theory.mohr_coulomb_angle` gives for b = 0 and 1 on a
    Drucker–Prager cone. NaN where σ1 + σ3 ≤ 0 (no compression); b NaN where σ1 = σ3."""
    a_b_k = principal_values(sig)  # tension +, a ≥ b ≥ k: the pressures are σ1 = −k ≥ σ2 = −b ≥ σ3 = −a
    s1, s2, s3 = -a_b_k[:, 2], -a_b_k[:, 1], -a_b_k[:, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        sin_phi = np.where(s1 + s3 > 0.0, (s1 - s3) / (s1 + s3), np.nan)
        b = np.where(s1 > s3, (s2 - s3) / (s1 - s3), np.nan)
    return np.degrees(np.arcsin(np.clip(sin_phi, 0.0, 1.0))), b


def wall_shear_capacity(sig, tan_beta: float):
    """The largest |σ_rz|/σ_rr the cohesionless Drucker–Prager cone q = p tan β admits at the
    normal stresses (rr, zz, θθ) of each of the (n, 4) stresses (tension +): the shear a wall
    whose plane is r = const can take from the solid beside it before that solid yields,

        σ_rz,max² = (p² tan²β − 3/2 |dev(σ_rr, σ_zz, σ_θθ)|²)/3,   q² = 3/2 |dev|² + 3 σ_rz²,

    over the wall's normal pressure −σ_rr. A wall of friction μ below it slides before the solid
    next to it yields; above it the solid there yields first and the wall can stick. The state's
    own σ_rz does not enter. Its maximum over the other two normal stresses is
    :func:`silo_dolfinx.theory.drucker_prager_wall_shear_limit`. 0 where the normal stresses
    alone are outside the cone; NaN where σ_rr ≥ 0 (no contact pressure)."""
    s = np.array(np.atleast_2d(sig), float)
    s[:, 3] = 0.0  # q of the normal stresses alone: q² − 3 σ_rz²
    p, q_normal = p_q(s)
    tau2 = ((p * tan_beta) ** 2 - q_normal**2) / 3.0
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(s[:, 0] < 0.0, np.sqrt(np.maximum(tau2, 0.0)) / -s[:, 0], np.nan)


def principal_angle(t_rr, t_zz, t_rz, major: str = "compressive"):
    """Angle (degrees, in (−90, 90]) from the r axis (horizontal) of the major principal
    direction of an in-plane symmetric tensor. 'compressive' picks the most negative
    eigenvalue (the major principal stress of a granular solid, tension positive);
    'largest' the most positive (the major principal plastic strain rate)."""
    t_rr, t_zz, t_rz = (np.asarray(a, float) for a in (t_rr, t_zz, t_rz))
    theta = 0.5 * np.degrees(np.arctan2(2.0 * t_rz, t_rr - t_zz))  # direction of the largest eigenvalue
    if major == "compressive":
        theta = theta + 90.0
    a = np.mod(theta, 180.0)
    return np.where(a > 90.0, a - 180.0, a)


def stress_orientation(sig):
    """Major (most compressive) principal stress angle from the horizontal, degrees: 90 is
    vertical (active, filling), 0 horizontal (passive, discharge; thesis Fig. 4-5)."""
    s = np.atleast_2d(np.asarray(sig, float))
    return principal_angle(s[:, 0], s[:, 1], s[:, 3], "compressive")


def strain_rate_orientation(d):
    """Major principal (plastic) strain-rate angle from the horizontal, degrees, of (n, 4)
    rates (rr, zz, θθ, γ_rz) with engineering shear."""
    d = np.atleast_2d(np.asarray(d, float))
    return principal_angle(d[:, 0], d[:, 1], 0.5 * d[:, 3], "largest")


def cell_oscillation(corners, values, decimals: int = 9) -> np.ndarray:
    """Each cell's value minus the mean of its edge neighbours' (0 for a cell without any):
    zero inside a linear field, ±2a for a checkerboard ±a - the measure of a spurious
    cell-to-cell mode (e.g. q/p above an outlet). Cells are (n, 4, 2) corner arrays (a
    snapshot's ``corners``); neighbours share an edge's two corners (to ``decimals``). NaN
    values (an undefined q/p) take no part: such a cell gets NaN, its neighbours average the
    others."""
    c = np.round(np.asarray(corners, float), decimals)
    n = c.shape[0]
    a = c.reshape(n * 4, 2)
    b = np.roll(c, -1, axis=1).reshape(n * 4, 2)
    lo = np.where((a[:, :1] < b[:, :1]) | ((a[:, :1] == b[:, :1]) & (a[:, 1:] < b[:, 1:])), a, b)
    hi = np.where(lo == a, b, a)
    key = np.concatenate([lo, hi], axis=1)
    _, inv = np.unique(key, axis=0, return_inverse=True)
    cell = np.repeat(np.arange(n), 4)
    order = np.argsort(inv.ravel(), kind="stable")
    e, cl = inv.ravel()[order], cell[order]
    pair = np.nonzero(e[1:] == e[:-1])[0]  # interior edges: two cells
    i, j = cl[pair], cl[pair + 1]
    v = np.asarray(values, float)
    ok = np.isfinite(v)
    w = np.where(ok, v, 0.0)
    s = np.bincount(i, w[j], n) + np.bincount(j, w[i], n)
    k = np.bincount(i, ok[j], n) + np.bincount(j, ok[i], n)
    return np.where(ok, np.where(k > 0, v - s / np.maximum(k, 1), 0.0), np.nan)


def cell_speed(snapshot: dict) -> np.ndarray:
    """Each cell's speed in a field snapshot: the mean |v| of its four corner nodes (corners and
    nodes matched by position)."""
    c = np.asarray(snapshot["corners"], float)
    n_nodes = len(snapshot["node_xy"])
    keys = np.round(np.concatenate([np.asarray(snapshot["node_xy"], float), c.reshape(-1, 2)]), 9)
    _, inv = np.unique(keys, axis=0, return_inverse=True)
    inv = inv.ravel()
    speed = np.zeros(inv.max() + 1)
    speed[inv[:n_nodes]] = np.linalg.norm(np.asarray(snapshot["node_velocity"], float), axis=1)
    return speed[inv[n_nodes:]].reshape(-1, 4).mean(axis=1)


def outlet_zone_oscillation(snapshot: dict, outlet_radius: float, zone: float = 0.15, flowing: float = 0.05,
                            field: str = "cell_q_over_p") -> dict:
    """The cell-to-cell oscillation of a snapshot's cell field (RMS of :func:`cell_oscillation`)
    in the outlet zone - the flowing cells whose centroid lies within ``zone`` of the outlet
    (r ≤ outlet_radius at z = 0) - against the rest of the flowing region (cells whose mean
    corner speed is at least ``flowing`` × the fastest cell's). Returns the two RMS values (over
    the cells where the field is defined), their ratio, the cell counts and the outlet zone's
    undefined (stress-free) cells: a spurious mode at the outlet shows as a ratio well above 1."""
    c = np.asarray(snapshot["corners"], float)
    speed = cell_speed(snapshot)
    moving = speed >= flowing * speed.max()
    centre = c.mean(axis=1)
    near = np.hypot(np.maximum(centre[:, 0] - outlet_radius, 0.0), centre[:, 1]) < zone
    osc = cell_oscillation(c, snapshot[field])
    defined = np.isfinite(osc)
    rms = [float(np.sqrt(np.mean(osc[sel] ** 2))) if sel.any() else float("nan")
           for sel in (moving & near & defined, moving & ~near & defined)]
    return {"outlet_rms": rms[0], "rest_rms": rms[1], "ratio": rms[0] / rms[1],
            "outlet_cells": int((moving & near).sum()), "rest_cells": int((moving & ~near).sum()),
            "outlet_stress_free": int((moving & near & ~defined).sum())}


def section_average(corners, values, z) -> np.ndarray:
    """Cross-section average at heights z of a cell field: ∫ v 2πr dA over the cells whose
    vertical extent contains z, divided by their ∫ 2πr dA (a volume-weighted mean over a
    one-cell-thick slab; nan if no cell spans z)."""
    c = np.asarray(corners, float)
    zlo, zhi = c[:, :, 1].min(axis=1), c[:, :, 1].max(axis=1)
    w = cell_areas(c) * c[:, :, 0].mean(axis=1)
    v = np.asarray(values, float)
    out = np.full(np.size(z), np.nan)
    for k, zk in enumerate(np.atleast_1d(z)):
        sel = (zlo <= zk) & (zhi >= zk)
        if np.any(sel):
            out[k] = np.sum(w[sel] * v[sel]) / np.sum(w[sel])
    return out


def lateral_pressure_ratio(snapshot: dict, wall_profile: dict, z) -> np.ndarray:
    """K(z) = wall normal pressure / cross-section mean vertical stress (both compressive),
    the definition of the issue on Janssen: p_h(z) / (−σ̄_zz(z))."""
    szz = section_average(snapshot["corners"], snapshot["cell_stress_zz"], z)
    ph = np.interp(z, wall_profile["z"], wall_profile["p_n"])
    return ph / -szz


# ---------------------------------------------------------------------------- ch. 5 rarefaction waves
@dataclass
class WaveGrowth:
    """A rarefaction wave's amplitude σ⁺ up a column and its fitted exponential growth."""

    x: np.ndarray  # distance travelled from the base (m), every station
    amplitude: np.ndarray  # σ⁺: the largest drop below the pre-wave value before the reflection (Pa)
    exponent: float  # b of σ⁺ = σ⁺0 exp(b x), 1/m (eq. 5-1: 1/(2 X0))
    stderr: float  # its standard error from the regression (1/m)
    sigma0: float  # σ⁺0: the fit's value at x = 0 (Pa)
    window: tuple[float, float]  # the stations' x range the fit used (m)

    @property
    def normalised(self) -> np.ndarray:
        """σ⁺/σ⁺0 (Figs. 5-6, 5-11/5-12)."""
        return self.amplitude / self.sigma0


@dataclass(frozen=True)
class Pull:
    """A column's base pulled at ``t_start``: the wave it launches travels at ``wave_speed`` up a
    column of ``length`` and its front takes ``rise`` s to pass a point."""

    t_start: float
    wave_speed: float
    length: float
    rise: float = 0.01


def rarefaction_growth(t, x, values, pull: Pull, fit: tuple[float, float | None] = (0.0, None),
                       sigma0: float | None = None) -> WaveGrowth:
    """Amplitude of a rarefaction wave launched at the base at t_start, station by station, and
    its growth exponent (thesis ch. 5, eq. 5-1).

    ``values`` (n_stations, n_times): a compressive stress (wall pressure, or −σ_zz on the
    axis) at heights ``x`` above the base, sampled at ``t``. At station x the wave arrives at
    t_start + x/c and its reflection from the top (a column of length L) at t_start +
    (2L − x)/c (``pull``); σ⁺(x) is the pre-wave value (the mean over ``rise`` s before t_start) minus
    the smallest value in between (of the history averaged over rise/5 s),
    the window closed ``pull.rise`` s before the reflection arrives (the time a front takes to pass
    a point: the pull's own rise, 5 ms in eq. 5-17, plus its smearing over a few cells) or at
    the record's end. A station gets an amplitude only if its front has passed ``rise`` s
    before the window closes (x ≤ L − c·rise) and it has a value throughout. ln σ⁺ = ln σ⁺0 + b x is fitted by least squares over those
    stations in ``fit`` = [x_min, x_max] (x_max None: L), b's standard error from the residuals. With ``sigma0`` given
    (the thesis normalises by "the initial magnitude generated by the boundary condition",
    ρ c u0 for a base pulled at u0), only b is fitted: ln(σ⁺/σ⁺0) = b x through the origin."""
    t_start, wave_speed, length, rise = pull.t_start, pull.wave_speed, pull.length, pull.rise
    x_min, x_max = fit
    t = np.asarray(t, float)
    x = np.asarray(x, float)
    v = np.atleast_2d(np.asarray(values, float))
    if v.shape != (x.size, t.size):
        raise ValueError(f"values: shape {v.shape}, expected (stations, times) = ({x.size}, {t.size})")
    keep = t >= t_start - rise  # (before it, e.g. during filling, a point may have no value)
    t, v = t[keep], v[:, keep]
    before = t <= t_start
    if not before.any():
        raise ValueError("no sample in [t_start − rise, t_start]: the pre-wave state is unknown")
    pre = v[:, before].mean(axis=1)
    # a moving average over rise/5 takes the sample-to-sample noise (ringing behind a front
    # smeared over a few cells) out of the minimum
    n = max(1, int(round(0.2 * rise / np.median(np.diff(t)))))
    if n > 1:
        from scipy.ndimage import uniform_filter1d

        v = uniform_filter1d(v, n, axis=1, mode="nearest")  # the record's ends are not padded with zeros
    amp = np.full(x.size, np.nan)
    for k in range(x.size):
        t_end = min(t_start + (2.0 * length - x[k]) / wave_speed - rise, t[-1])
        win = (t > t_start) & (t <= t_end)
        if t_end >= t_start + x[k] / wave_speed + rise and win.any() and np.all(np.isfinite(v[k, win])):
            amp[k] = pre[k] - np.min(v[k, win])
    hi = length if x_max is None else x_max
    use = (x >= x_min) & (x <= hi) & np.isfinite(amp) & (amp > 0)
    if use.sum() < 3:
        raise ValueError(f"{int(use.sum())} stations in the fit window [{x_min:g}, {hi:g}] m with a wave: need 3")
    X, Y = x[use], np.log(amp[use])
    if sigma0 is not None:
        Y = Y - np.log(sigma0)
    A = np.column_stack([np.ones_like(X), X]) if sigma0 is None else X[:, None]
    coef, *_ = np.linalg.lstsq(A, Y, rcond=None)
    resid = Y - A @ coef
    dof = max(X.size - A.shape[1], 1)
    cov = np.linalg.inv(A.T @ A) * float(resid @ resid) / dof
    return WaveGrowth(x, amp, float(coef[-1]), float(np.sqrt(cov[-1, -1])),
                      float(np.exp(coef[0])) if sigma0 is None else float(sigma0), (float(X.min()), float(X.max())))


def station_matrix(history: dict, key: str, column: str, sign: float = 1.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t, heights, values (n, n_t)) of a history file read by :func:`silo_dolfinx.output.read_csv`
    — wall_history.csv (key "station") or point_history.csv (key "point") — each series
    interpolated onto the union of the sample times, times ``sign`` (−1 turns a tensile-positive
    stress into a pressure). The height is each station's last (its wall node is placed once
    its layer is active)."""
    t = np.unique(history["t"])
    ids = np.unique(history[key])
    rows, z = [], []
    for k in ids:
        m = history[key] == k
        rows.append(np.interp(t, history["t"][m], sign * history[column][m]))
        z.append(history["z"][m][-1])
    return t, np.array(z), np.array(rows)


# ---------------------------------------------------------------------------- run health
def run_health(folder) -> dict:
    """The hard-case checks of a results folder (tests/test_hard_cases.py, benchmarks/soak.py,
    docs/reliability.md): the run's status; the largest energy-balance error (fraction of the
    energy scale) and mass-balance error (fraction of the mass at opening) over every sample;
    the worst cell (min scaled Jacobian over every sample: > 0 means no inverted cell - the solver
    also stops on one at any step); whether every number written is finite; the largest wall
    pressure as a multiple of ρ g H (H the fill height); the discharged mass, steps and Δt range."""
    from pathlib import Path

    from silo_dolfinx.output import read_csv, read_summary
    from silo_dolfinx.scene import load_scene

    folder = Path(folder)
    s = read_summary(folder)
    sc = load_scene(folder / "scene.toml")
    tables = {n: read_csv(folder / f"{n}.csv") for n in ("energy", "outlet", "mesh_quality", "wall_history")}
    finite = all(np.all(np.isfinite(v)) for t in tables.values() if t is not None
                 for v in t.values() if np.asarray(v).dtype.kind == "f")
    o, q, w = tables["outlet"], tables["mesh_quality"], tables["wall_history"]
    rho_g_h = sc.material.density * sc.loads.gravity * sc.outline.fill_height
    return {"status": s.get("status", "missing"),
            "energy_error_max": s.get("energy_balance_error_max", float(np.nanmax(np.abs(tables["energy"]["relative_error"])))
                                      if tables["energy"] else np.nan),
            "mass_error_max": float(np.abs(o["mass_balance_error"]).max()) if o is not None else np.nan,
            "min_scaled_jacobian": float(q["min_scaled_jacobian"].min()) if q is not None else np.nan,
            "finite": bool(finite),
            "p_max_over_rho_g_h": float(np.nanmax(w["p_n"]) / rho_g_h) if w is not None else np.nan,
            "discharged_mass": float(o["discharged_mass"][-1]) if o is not None else 0.0,
            "mass_at_opening": float(o["mass_in_silo"][0] + o["discharged_mass"][0]) if o is not None else np.nan,
            "steps": s.get("steps", 0),  # (a run that stopped: its time is the last energy sample's)
            "simulated_time": s.get("simulated_time", float(tables["energy"]["t"][-1]) if tables["energy"] else np.nan),
            "dt_min": float(np.nanmin(o["dt"])) if o is not None else np.nan,
            "error": s.get("error", "")}
