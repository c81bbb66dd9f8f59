"""The virtual vibrometer (granchain.vibrometer): the scene's measurement block, the
filter against theory, noise, extraction on analytic pulses, and the unmeasured and
not-final paths."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from granchain import vibrometer
from granchain import tables
from granchain.cli import main
from granchain.errors import SceneError
from granchain.observables import MEASURED_COLUMNS, MEASURED_FIELDS
from granchain.scene import load_scene
from granchain.scenecheck import Measurement
from granchain.simulate import run_scene

from conftest import SCENES, packed


def meas(**kw) -> Measurement:
    base = dict(bandwidth_hz=2.5e6, filter="butterworth", order=4, sampling_rate_hz=20e6,
                noise_rms_m_s=0.0, seed=0)
    base.update(kw)
    return Measurement(**base)


# ---------------------------------------------------------------------------------------
# the scene block
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("text, field, words", [
    ("measurement: {bandwith_hz: 1.0e6}", "measurement.bandwith_hz", "did you mean 'measurement.bandwidth_hz'"),
    ("measurement: {filter: besel}", "measurement.filter", "did you mean 'bessel'"),
    ("measurement: {filter: chebyshev}", "measurement.filter", "use one of butterworth, bessel"),
    ("measurement: {order: 0}", "measurement.order", "from 1 to 10"),
    ("measurement: {order: 2.5}", "measurement.order", "whole number"),
    ("measurement: {bandwidth_hz: -1}", "measurement.bandwidth_hz", "> 0"),
    ("measurement: {bandwidth_hz: abc}", "measurement.bandwidth_hz", "expected a number"),
    ("measurement: {sampling_rate_hz: 4.0e6}", "measurement.sampling_rate_hz", "twice the bandwidth"),
    ("measurement: {bandwidth_hz: 5.0e6, sampling_rate_hz: 1.0e7}", "measurement.sampling_rate_hz",
     "sampling_rate_hz > 1e+07"),
    ("measurement: {noise_rms_m_s: -0.1}", "measurement.noise_rms_m_s", ">= 0"),
    ("measurement: {noise_rms_m_s: 0.001, seed: -2}", "measurement.seed", ">= 0"),
    ("measurement: {seed: 3}", "measurement.seed", "has no effect without noise"),
    ("measurement: 2.5e6", "measurement", "expected a mapping"),
])
def test_bad_measurement_blocks_are_one_line(tmp_path, capsys, text, field, words):
    p = tmp_path / "s.yaml"
    p.write_text(text + "\n")
    assert main(["validate", str(p)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert f"'{field}'" in err and words in err, err


def test_measurement_defaults_and_overrides():
    s = load_scene(SCENES / "packed-440c.yaml", ["measurement.filter=bessel",
                                                 "measurement.bandwidth_hz=1.0e6"])
    assert s.measurement == meas(filter="bessel", bandwidth_hz=1e6)
    assert s.spec["measurement"]["order"] == 4 and vibrometer.needs_trace(s)
    # a measured scene hashes differently from the same scene unmeasured, and the
    # instrument's settings are part of the hash
    plain = load_scene(SCENES / "packed-440c.yaml")
    assert plain.measurement is None and "measurement" not in plain.spec
    assert not vibrometer.needs_trace(plain) and plain.hash != s.hash
    assert s.derive(**{"measurement.order": 2}).hash != s.hash
    assert s.derive(**{"measurement.order": 2}).measurement.order == 2
    with pytest.raises(SceneError, match="measurement.sampling_rate_hz"):
        s.derive(**{"measurement.bandwidth_hz": 2e7})


# ---------------------------------------------------------------------------------------
# the filter against theory
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("order", [1, 2, 4, 8])
def test_butterworth_magnitude_is_the_prewarped_butterworth_law(order):
    """Bilinear transform with the bandwidth pre-warped: |H(f)|^2 = 1 / (1 + (tan(pi f/fs)
    / tan(pi fc/fs))^(2n)) exactly; so unit gain at DC and -3 dB at the bandwidth."""
    m = meas(order=order)
    f = np.array([0.0, 0.3e6, 1e6, 2.5e6, 4e6, 8e6])
    h2 = np.abs(vibrometer.response(m, f)) ** 2
    fs, fc = m.sampling_rate_hz, m.bandwidth_hz
    theory = 1.0 / (1.0 + (np.tan(np.pi * f / fs) / np.tan(np.pi * fc / fs)) ** (2 * order))
    assert h2 == pytest.approx(theory, rel=1e-9, abs=1e-14)
    assert h2[0] == pytest.approx(1.0, abs=1e-12) and h2[3] == pytest.approx(0.5, rel=1e-9)


@pytest.mark.parametrize("order", [1, 2, 3, 5, 8])
def test_bessel_is_minus_3_db_at_the_bandwidth_with_unit_dc_gain(order):
    m = meas(filter="bessel", order=order)
    h = np.abs(vibrometer.response(m, [0.0, m.bandwidth_hz]))
    assert h[0] == pytest.approx(1.0, abs=1e-12)
    assert 20 * np.log10(h[1]) == pytest.approx(-10 * np.log10(2), abs=1e-6)
    # a step settles at 1 (DC gain of the recorded samples)
    rec = vibrometer.record(np.linspace(0, 20e-6, 20001), np.ones(20001), m)
    assert rec.v[-1] == pytest.approx(1.0, abs=1e-9)


@pytest.mark.parametrize("order, denominator", [
    (2, [1, 3, 3]),                     # Bessel polynomials, delay-normalised (tau0 = 1)
    (4, [1, 10, 45, 105, 105]),
])
def test_bessel_group_delay_matches_the_textbook_polynomial(order, denominator):
    """H(s) = theta_n(0) / theta_n(s) has DC group delay 1 in units where its -3 dB
    frequency is w3 (|theta_n(j w3)|^2 = 2 theta_n(0)^2): so the filter with -3 dB at f_c
    delays by w3 / (2 pi f_c). Order 2: w3^2 = (sqrt(45) - 3) / 2."""
    d = np.poly1d(denominator)
    # |D(jw)|^2 as a polynomial in w: D(jw) D(-jw)
    dj = np.poly1d([c * (1j) ** k for k, c in enumerate(denominator[::-1])][::-1])
    dmj = np.poly1d([c * (-1j) ** k for k, c in enumerate(denominator[::-1])][::-1])
    mag2 = np.real((dj * dmj).coeffs)
    roots = np.roots(np.polysub(mag2, [2 * d(0) ** 2]))
    w3 = float(min(r.real for r in roots if abs(r.imag) < 1e-9 and r.real > 0))
    if order == 2:
        assert w3 == pytest.approx(math.sqrt((math.sqrt(45) - 3) / 2), rel=1e-12)
    fc = 1e6
    m = meas(filter="bessel", order=order, bandwidth_hz=fc, sampling_rate_hz=400 * fc)
    tau = vibrometer.group_delay(m, [1e3])[0]
    assert tau == pytest.approx(w3 / (2 * math.pi * fc), rel=2e-3)
    # and the delay is flat in the passband (the point of a Bessel filter)
    assert vibrometer.group_delay(m, [0.3 * fc])[0] == pytest.approx(tau, rel=0.02)


def test_first_order_filter_on_a_rectangular_pulse():
    """An RC low-pass (order 1, tau = 1/(2 pi f_c)) driven by a unit pulse of width T
    peaks at the pulse's end with 1 - exp(-T/tau); the front (half-peak) crosses at
    tau ln(1 / (1 - peak/2))."""
    fc, T = 1e6, 0.5e-6
    m = meas(order=1, bandwidth_hz=fc, sampling_rate_hz=2000 * fc)
    tau = 1 / (2 * math.pi * fc)
    t = np.linspace(0, 5e-6, 500001)
    v = ((t > 0) & (t <= T)).astype(float)
    rec = vibrometer.record(t, np.column_stack([v, v]), m)
    out = vibrometer.extract(rec.t, rec.v)
    peak = 1 - math.exp(-T / tau)
    assert out.v_max_1 == pytest.approx(peak, rel=2e-3)
    assert out.t_peak[0] == pytest.approx(T, abs=2e-9)
    assert out.t_front[0] == pytest.approx(tau * math.log(1 / (1 - peak / 2)), rel=5e-3)


def test_identical_pulses_keep_their_delay_through_the_same_filter():
    """A causal filter delays a pulse, but the same filter on both probes delays both
    equally: the peak-to-peak delay of two copies of one pulse is their true delay,
    while each peak time moves by about the group delay (Bessel, narrow-band pulse)."""
    m = meas(filter="bessel", order=4, sampling_rate_hz=100e6)
    t = np.arange(0, 30e-6, 2e-9)
    sig, delay = 1.0e-6, 7.3e-6
    g = lambda t0: 0.5 * np.exp(-0.5 * ((t - t0) / sig) ** 2)   # noqa: E731
    rec = vibrometer.record(t, np.column_stack([g(5e-6), g(5e-6 + delay)]), m)
    out = vibrometer.extract(rec.t, rec.v, span=11 * 300e-6)
    assert out.dt_peak == pytest.approx(delay, abs=1e-10)
    assert out.dt_front == pytest.approx(delay, abs=1e-10)
    assert out.v_g == pytest.approx(11 * 300e-6 / delay, rel=1e-4)
    tau0 = vibrometer.group_delay(m, [1e3])[0]
    assert out.t_peak[0] - 5e-6 == pytest.approx(tau0, rel=0.02)
    # a pulse this wide keeps its peak: a Bessel filter is nearly Gaussian, impulse
    # response sigma_h = sqrt(ln 2) / (2 pi f_c), so the peak drops by a factor
    # sigma / sqrt(sigma^2 + sigma_h^2) = 0.9986; one 10x narrower loses 12 %
    sig_h = math.sqrt(math.log(2)) / (2 * math.pi * m.bandwidth_hz)
    assert out.v_max_1 / 0.5 == pytest.approx(sig / math.hypot(sig, sig_h), abs=1e-3)
    narrow = 0.5 * np.exp(-0.5 * ((t - 5e-6) / (sig / 10)) ** 2)
    rec = vibrometer.record(t, np.column_stack([narrow, narrow]), m)
    assert vibrometer.extract(rec.t, rec.v).v_max_1 / 0.5 == pytest.approx(
        sig / 10 / math.hypot(sig / 10, sig_h), abs=5e-3)


def test_extraction_refines_the_peak_between_samples():
    """A pulse sampled at 20 MS/s: the recorded peak and its time are found between
    samples (the observables' parabola), as the experiment reads them."""
    t = np.arange(0, 20e-6, 50e-9)
    t1, t2 = 3.0123e-6, 11.7771e-6
    y = np.column_stack([0.8 * np.exp(-0.5 * ((t - t1) / 0.6e-6) ** 2),
                         0.6 * np.exp(-0.5 * ((t - t2) / 0.6e-6) ** 2)])
    out = vibrometer.extract(t, y, span=1.0)
    assert out.v_max == pytest.approx((0.8, 0.6), rel=2e-4)
    assert out.t_peak == pytest.approx((t1, t2), abs=1e-9)
    assert out.dt_peak == pytest.approx(t2 - t1, abs=2e-9) and out.final == (True, True)
    # the half-peak front of a Gaussian: t0 - sigma sqrt(2 ln 2)
    assert out.dt_front == pytest.approx(t2 - t1, abs=2e-9)
    assert out.t_front[0] == pytest.approx(t1 - 0.6e-6 * math.sqrt(2 * math.log(2)), abs=2e-9)


def test_a_cut_record_or_a_peak_not_final_is_nan_with_a_flag():
    t = np.arange(0, 10e-6, 10e-9)
    whole = np.exp(-0.5 * ((t - 3e-6) / 0.5e-6) ** 2)
    cut = np.exp(-0.5 * ((t - 9.8e-6) / 0.5e-6) ** 2)        # still rising at the end
    out = vibrometer.extract(t, np.column_stack([whole, cut]), span=1.0)
    assert out.final == (True, False)
    assert out.v_max_1 == pytest.approx(1.0, rel=1e-4)
    assert math.isnan(out.v_max_2) and math.isnan(out.t_peak[1])
    assert math.isnan(out.dt_peak) and math.isnan(out.dt_front) and math.isnan(out.v_g)
    # the filter delays the peak past the end of a record that holds the true peak
    late = np.exp(-0.5 * ((t - 9.2e-6) / 0.2e-6) ** 2)
    assert vibrometer.extract(t, np.column_stack([whole, late])).final == (True, True)
    rec = vibrometer.record(t, np.column_stack([whole, late]), meas(filter="bessel", bandwidth_hz=0.5e6))
    assert vibrometer.extract(rec.t, rec.v).final == (True, False)
    # a true peak that is not final is not measured either
    out = vibrometer.extract(t, np.column_stack([whole, whole]), true_final=(False, True))
    assert out.final == (False, True) and math.isnan(out.v_max_1)


def test_noise_is_white_reproducible_and_seeded():
    t = np.arange(0, 2e-3, 25e-9)     # 40 000 recorded samples: correlations +/- 0.005
    v = np.column_stack([np.zeros_like(t), np.zeros_like(t)])
    m = meas(noise_rms_m_s=0.01, seed=5)
    a = vibrometer.record(t, v, m, key=(3,))
    assert np.array_equal(a.v, vibrometer.record(t, v, m, key=(3,)).v)
    assert not np.array_equal(a.v, vibrometer.record(t, v, m, key=(4,)).v)
    assert not np.array_equal(a.v, vibrometer.record(t, v, dataclasses.replace(m, seed=6), key=(3,)).v)
    assert a.v.std() == pytest.approx(0.01, rel=0.02)
    # white: neighbouring samples uncorrelated; the two probes independent
    x = a.v[:, 0]
    assert abs(np.corrcoef(x[:-1], x[1:])[0, 1]) < 0.02
    assert abs(np.corrcoef(a.v[:, 0], a.v[:, 1])[0, 1]) < 0.02
    # without noise the record is the filtered signal alone
    assert np.array_equal(vibrometer.record(t, v, meas()).v, np.zeros_like(a.v))


# ---------------------------------------------------------------------------------------
# results: measured and unmeasured runs
# ---------------------------------------------------------------------------------------
def test_unmeasured_runs_have_no_measured_values_anywhere():
    run, = run_scene(packed(**{"chain.n": 6, "probes": "[2, 6]"}))
    assert not run.measured and run.v_max_1_measured is None
    assert not set(MEASURED_FIELDS) & set(run.to_json())
    assert not set(MEASURED_COLUMNS) & set(run.to_row())
    assert not set(MEASURED_COLUMNS) & set(tables.columns(6))


def test_measured_run_fills_json_rows_and_tables():
    sc = packed(**{"chain.n": 8, "probes": "[2, 7]", "measurement.filter": "bessel"})
    run, = run_scene(sc)
    assert run.measured and run.measured_not_final == ()
    rec = vibrometer.measure(_traj(sc), sc.probes, sc.measurement, key=(0,))
    assert run.v_max_1_measured == rec.v_max_1 and run.dt_peak_measured == rec.dt_peak
    # a Bessel filter does not overshoot: the recorded peaks lie below the true ones
    assert 0.9 * run.v_max_1 < run.v_max_1_measured < run.v_max_1
    assert 0.9 * run.v_max_2 < run.v_max_2_measured < run.v_max_2
    assert run.dt_peak_measured == pytest.approx(run.dt_peak, rel=0.05)
    doc = run.to_json()
    assert set(MEASURED_FIELDS) <= set(doc) and doc["measured"] is True
    meta = {"study": "s", "material": "ss440c", "gap_distribution": "none",
            "gap_mean_nm": 0.0, "extra_length_um": 0.0, "seed": 0, "scene_hash": "h"}
    row = tables.member_row(meta, run, 8)
    assert list(row) == tables.columns(8, measured=True)
    assert row["v_max_1_measured_m_s"] == run.v_max_1_measured
    df = tables.study_table([row], 8)
    summ = tables.summary_table(df)
    assert list(summ.columns) == tables.summary_columns(measured=True)
    assert summ["v_max_1_measured_m_s_p50"].iloc[0] == run.v_max_1_measured


def _traj(scene):
    from granchain.simulate import trajectories
    from granchain.gaps import members
    (_, traj), = list(trajectories(scene, members(scene)))
    return traj


def test_a_bad_vibrometer_study_setting_is_one_line():
    """Every instrument setting of the workflow's vibrometer study is validated as a
    measurement block when the plan is built, before anything runs."""
    from granchain import workflow as gw
    cfg = gw.read_config(SCENES.parents[1] / "config" / "config.yaml", "tiny")
    cfg["presets"]["tiny"]["studies"]["vibrometer"]["bandwidth_hz"] = [1.0e6, 6.0e7]
    with pytest.raises(gw.ConfigError) as exc:
        gw.Plan.build(cfg)
    msg = str(exc.value)
    assert "\n" not in msg and "presets.tiny.studies.vibrometer" in msg
    assert "measurement.sampling_rate_hz" in msg and "twice the bandwidth 6e+07" in msg


def _faster_than_sound(sc):
    """A record of 15 spheres whose pulse peaks 20 ns apart per sphere: 15 km/s, above
    the bar sound speed of 440C; with the limits of ``sc``."""
    from granchain import guards
    from granchain.trajectory import ENERGY_COLUMNS, RunInfo, Trajectory
    t = np.arange(8000) * 5e-9
    v = np.stack([0.05 * np.exp(-((t - 5e-6 - 2e-8 * i) / 3e-7) ** 2) for i in range(15)],
                 axis=1)
    return Trajectory(t=t, v=v, energy=np.ones((t.size, len(ENERGY_COLUMNS))),
                      gaps=np.zeros(14), radius=150e-6, v_striker=0.1, status="passed",
                      last_overlap=-1e-9, info=RunInfo(method="rk4", dt=1e-9),
                      limits=guards.result_limits(sc))


def test_the_study_table_sets_an_impossible_recorded_value_aside():
    """The vibrometer study's rows go through the run's physical bounds as the run table's
    do: a pulse between the probes faster than the bar sound speed of 440C is NaN in both
    the true and the recorded columns, with status unphysical and a line naming the key.
    (The recorded v_g, 1.5e4 m/s, was a number in the table with status passed before.)"""
    from types import SimpleNamespace
    from granchain.gaps import members
    from granchain.workflow import vibrometer as wv

    sc = packed(**{"measurement.filter": "bessel"})
    traj = _faster_than_sound(sc)
    ss = SimpleNamespace(scene=sc, material="ss440c", gap_mean_nm=0.0)
    row, = wv._rows(ss, [sc.measurement], members(sc)[0], traj)
    raw = vibrometer.measure(traj, sc.probes, sc.measurement, key=(0,))
    assert raw.v_g > 1e4                         # what the instrument alone reads
    for col in ("v_g_m_s", "dt_peak_s", "v_g_measured_m_s", "dt_peak_measured_s",
                "dt_peak_bias_s"):
        assert math.isnan(row[col]), col
    assert row["status"] == "unphysical"
    assert "v_g_measured" in row["warnings"] and "sound speed" in row["warnings"]
    assert row["v_max_2_measured_m_s"] == raw.v_max_2      # a possible value is kept
    assert list(row) == list(wv.VIB_COLUMNS)


def test_the_study_progress_line_says_which_chains_were_unphysical(monkeypatch, capsys):
    """The study's progress line says how many of its rows did not end as planned, as the
    table's status column does (it said only 'N chains x M settings in X s')."""
    from granchain import workflow as gw
    from granchain.workflow import vibrometer as wv
    _, P = gw.load_config(SCENES.parents[1] / "config" / "config.yaml", "tiny")
    monkeypatch.setattr(wv, "trajectories", lambda sc, mem, engine: (
        (m, _faster_than_sound(sc)) for m in mem))
    df, _, _ = wv.run_vibrometer(P)
    err = capsys.readouterr().err
    assert (df["status"] == "unphysical").all()
    assert "runs ended unphysical" in err and "status and warnings columns" in err
