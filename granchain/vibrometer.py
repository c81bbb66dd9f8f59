"""The virtual laser vibrometer: what the instrument records of the probes' velocities.

A scene's ``measurement:`` block (:class:`granchain.scenecheck.Measurement`) describes the
instrument. :func:`record` turns the true velocity histories of the probes (a
Trajectory's ``t`` and ``v`` columns) into the recorded signals:

1. resample onto the digitiser's grid t_k = t_0 + k / sampling_rate_hz (linear
   interpolation of the run's samples, which are much finer: ~400 per pulse width);
2. apply a causal low-pass: the analog Butterworth or Bessel prototype of the given
   order with its -3 dB point at ``bandwidth_hz`` (Bessel: magnitude-normalised), made
   digital for the sampling rate by the bilinear transform with the bandwidth pre-warped
   (so the digital filter is exactly -3 dB at ``bandwidth_hz``), run from rest as
   second-order sections. A causal filter is what an instrument does: it delays the
   recorded pulse (a Bessel filter by its nearly constant group delay, w_3 / (2 pi f_c)
   with w_3 = 1.36 for order 2 and 2.11 for order 4: 0.135 us at 2.5 MHz and order 4)
   and broadens it. The
   delay cancels in the peak-to-peak delay dt only when both probes see the same filter,
   as they do here; two vibrometers with different decoders would bias dt by the
   difference of their delays;
3. add white noise of RMS ``noise_rms_m_s`` to every recorded sample, drawn from
   ``numpy.random.default_rng([seed, *key])`` (``key``: the member index in
   ``simulate.run_scene``, so every chain has its own reproducible noise).

:func:`extract` reads the recorded signals as the experiment does: the peak value of
each probe (v_max,1, v_max,2), the delay between the peak times (dt) and the delay
between the half-peak front times, with the peak refined between samples by
:func:`granchain.observables.peak` (the same rule as the true observables). A recorded
peak is *final* when the true peak of that probe is final and the recorded signal has
fallen below half its peak after it (``stoprule.inner_passed``: the filtered pulse has
passed the instrument inside the record); otherwise its values are NaN and the probe is
listed in ``not_final``.

:func:`needs_trace` is the one place that says a run must keep the probes' velocity
histories for the instrument.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .observables import peak, probe_span
from .scenecheck import Measurement
from .stoprule import inner_passed
from .trajectory import Trajectory


def needs_trace(scene) -> bool:
    """Does a run of ``scene`` need the probes' full velocity histories? True for a
    measured scene (the vibrometer filters the whole history of each probe)."""
    return scene.measurement is not None


def prewarped(m: Measurement) -> float:
    """Analog -3 dB angular frequency (rad/s) whose bilinear image at the sampling rate
    is ``bandwidth_hz``: 2 fs tan(pi f_c / fs)."""
    fs = m.sampling_rate_hz
    return 2.0 * fs * math.tan(math.pi * m.bandwidth_hz / fs)


def analog_prototype(m: Measurement, wc: float | None = None):
    """(zeros, poles, gain) of the analog low-pass of ``m`` with -3 dB at ``wc`` rad/s
    (default 2 pi bandwidth_hz)."""
    from scipy import signal
    wc = 2.0 * math.pi * m.bandwidth_hz if wc is None else wc
    if m.filter == "butterworth":
        return signal.butter(m.order, wc, analog=True, output="zpk")
    if m.filter == "bessel":
        return signal.bessel(m.order, wc, analog=True, output="zpk", norm="mag")
    raise ValueError(f"unknown filter {m.filter!r}")


def design(m: Measurement) -> np.ndarray:
    """Second-order sections of the digital filter of ``m`` at its sampling rate."""
    from scipy import signal
    z, p, k = analog_prototype(m, prewarped(m))
    zd, pd, kd = signal.bilinear_zpk(z, p, k, m.sampling_rate_hz)
    return signal.zpk2sos(zd, pd, kd)


def response(m: Measurement, f: np.ndarray) -> np.ndarray:
    """Complex frequency response of the digital filter at frequencies ``f`` (Hz)."""
    from scipy import signal
    _, h = signal.sosfreqz(design(m), worN=np.asarray(f, dtype=float), fs=m.sampling_rate_hz)
    return h


def group_delay(m: Measurement, f: np.ndarray) -> np.ndarray:
    """Group delay (s) of the digital filter at frequencies ``f`` (Hz), from the phase."""
    f = np.asarray(f, dtype=float)
    df = 1e-4 * m.bandwidth_hz
    ph = np.unwrap(np.angle(response(m, np.concatenate([f - df, f + df]))))
    lo, hi = ph[:f.size], ph[f.size:]
    return -(hi - lo) / (2.0 * math.pi * 2.0 * df)


@dataclass(frozen=True)
class Record:
    """What the vibrometers record: t (K,) s on the digitiser's grid, v (K, P) m/s (one
    column per probe), and the true velocities resampled onto the same grid."""
    t: np.ndarray
    v: np.ndarray
    true: np.ndarray


def record(t: np.ndarray, v: np.ndarray, m: Measurement, key=()) -> Record:
    """The recorded signals of true histories ``v`` (S,) or (S, P) sampled at ``t`` (S,).

    ``key``: integers that, with ``m.seed``, pick the noise stream."""
    from scipy import signal
    t = np.asarray(t, dtype=float)
    v = np.asarray(v, dtype=float)
    v2 = v[:, None] if v.ndim == 1 else v
    fs = m.sampling_rate_hz
    k = int(math.floor((t[-1] - t[0]) * fs * (1.0 + 1e-12))) + 1
    tk = t[0] + np.arange(k) / fs
    x = np.column_stack([np.interp(tk, t, v2[:, j]) for j in range(v2.shape[1])])
    y = signal.sosfilt(design(m), x, axis=0)
    if m.noise_rms_m_s > 0:
        rng = np.random.default_rng([int(m.seed), *(int(i) for i in key)])
        y = y + m.noise_rms_m_s * rng.standard_normal(y.shape)
    if v.ndim == 1:
        return Record(tk, y[:, 0], x[:, 0])
    return Record(tk, y, x)


@dataclass(frozen=True)
class Measured:
    """The experiment's observables read off a record (NaN where not final).

    v_max, t_peak, t_front: per probe; final: per probe; v_max_1, v_max_2: the probes'
    recorded peaks; dt_peak, dt_front: delays between the probes' peak and half-peak
    front times; v_g, v_g_front: span / dt (span: the probes' distance along the chain,
    ``observables.probe_span``)."""
    v_max: tuple[float, ...]
    t_peak: tuple[float, ...]
    t_front: tuple[float, ...]
    final: tuple[bool, ...]
    dt_peak: float
    dt_front: float
    v_g: float
    v_g_front: float

    @property
    def v_max_1(self) -> float:
        return self.v_max[0]

    @property
    def v_max_2(self) -> float:
        return self.v_max[-1]

    def result_fields(self, probes) -> dict:
        """The measured fields of :class:`granchain.observables.ChainResult`."""
        return {"measured": True, "v_max_1_measured": self.v_max_1,
                "v_max_2_measured": self.v_max_2, "dt_peak_measured": self.dt_peak,
                "dt_front_measured": self.dt_front, "v_g_measured": self.v_g,
                "v_g_front_measured": self.v_g_front,
                "measured_not_final": tuple(int(p) for p, f in zip(probes, self.final)
                                            if not f)}


def extract(t: np.ndarray, y: np.ndarray, span: float = math.nan,
            true_final=None) -> Measured:
    """Peaks, peak-to-peak and front delays of recorded signals ``y`` (K, 2) at ``t``.

    ``true_final``: per probe, is its true peak final (default: yes); ``span``: the
    probes' distance (m) for v_g."""
    y = np.asarray(y, dtype=float)
    if y.ndim != 2 or y.shape[1] < 2:
        raise ValueError(f"extract needs (K, 2) signals, got shape {y.shape}")
    if true_final is None:
        true_final = (True,) * y.shape[1]
    vm, tp, tf, fin = [], [], [], []
    for j in range(y.shape[1]):
        vmax, tpk, tfr, _ = peak(t, y[:, j])
        i = int(np.argmax(y[:, j]))
        ok = bool(true_final[j] and vmax > 0 and i < y.shape[0] - 1
                  and inner_passed(y[i + 1:, j], vmax))
        vm.append(vmax if ok else math.nan)
        tp.append(tpk if ok else math.nan)
        tf.append(tfr if ok else math.nan)
        fin.append(ok)
    both = fin[0] and fin[-1]
    dt_peak = tp[-1] - tp[0] if both else math.nan
    dt_front = tf[-1] - tf[0] if both else math.nan
    v_g = span / dt_peak if both and dt_peak > 0 else math.nan
    v_g_front = span / dt_front if both and dt_front > 0 else math.nan
    return Measured(tuple(map(float, vm)), tuple(map(float, tp)), tuple(map(float, tf)),
                    tuple(fin), float(dt_peak), float(dt_front), float(v_g), float(v_g_front))


def measure(traj: Trajectory, probes, m: Measurement, key=(), true_final=None) -> Measured:
    """The vibrometers of ``m`` on the probes (1-based) of a trajectory: record, then
    extract. ``true_final``: per probe, is its true peak final (``observables.peaks``)."""
    cols = [int(p) - 1 for p in probes]
    rec = record(traj.t, traj.v[:, cols], m, key)
    _, span = probe_span(traj, probes)
    return extract(rec.t, rec.v, span, true_final)
