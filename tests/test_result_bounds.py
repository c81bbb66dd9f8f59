"""After a run: a value outside its physical bounds (a group velocity above the bar sound
speed of the chain's stiffest material, a delay that is not positive, a non-finite value)
is NaN, named in ``out_of_bounds``, explained by a warning naming the scene key at fault,
and never carries status passed; the human output says so, and shows every status other
than passed or done."""
from __future__ import annotations

import contextlib
import dataclasses
import io
import math

import numpy as np
import pytest

from granchain import cli, guards
from granchain.commands import run as run_command
from granchain.observables import bounded, summarize
from granchain.scene import scene_from_dict
from granchain.simulate import run_scene, trajectories
from granchain.gaps import members
from granchain.trajectory import ENERGY_COLUMNS, Trajectory

# a valid preloaded chain (static overlap 1e-3 R); the test pushes its dead load to 1e3 N
# (static overlap 0.57 R) behind the validator's back, as a scene the validator
# happened to let through would be
WALLED = {"name": "walled", "material": "ss440c", "chain": {"n": 15, "radius": 150e-6},
          "striker": {"velocity": 0.1}, "walls": {"end": "rigid"},
          "precompression": {"force": 0.1}, "integrator": {"method": "rk4", "dt": 1e-9}}


def preloaded(force: float):
    return dataclasses.replace(scene_from_dict(WALLED), precompression=force)


def pulses(peak_times, n=15, S=4000, width=2e-8, dt=1e-9):
    """Velocity records of n particles, one Gaussian pulse each at the given peak times
    (s), sampled every dt: each pulse rises and falls inside the record, so its peak is
    final."""
    t = np.arange(S) * dt
    v = np.stack([0.05 * np.exp(-((t - tp) / width) ** 2) for tp in peak_times], axis=1)
    return t, v


def synthetic(v, t, *, limits=None, energy=None, status="passed"):
    S, n = v.shape
    e = np.ones((S, len(ENERGY_COLUMNS))) if energy is None else energy
    return Trajectory(t=t, v=v, energy=e, gaps=np.zeros(n - 1), radius=150e-6,
                      v_striker=0.1, status=status, last_overlap=-1e-9, limits=limits)


def test_the_limit_is_the_bar_speed_of_the_stiffest_sphere():
    mixed = scene_from_dict({"name": "mixed", "chain": {
        "n": 4, "radius": 150e-6, "materials": ["ptfe", "ss440c", "tungsten_carbide", "ss440c"]},
        "striker": {"velocity": 0.1}, "probes": [2, 4]})
    lim = guards.result_limits(mixed)
    wc = next(m for m in mixed.materials if m.name == "tungsten_carbide")
    assert lim.material == "tungsten_carbide"
    assert lim.sound_speed == pytest.approx(math.sqrt(wc.E / wc.rho), rel=1e-15)


def test_a_wave_faster_than_sound_is_not_reported_and_names_the_preload():
    """Fails on a build without the bounds: v_g = 6.0e3 m/s (above the 5.06e3 m/s of
    440C) came out with status passed."""
    scene = preloaded(1e3)
    r, = run_scene(scene)
    assert math.isnan(r.v_g) and math.isnan(r.dt_peak)
    assert {"v_g", "dt_peak"} <= set(r.out_of_bounds)
    assert r.status == "unphysical"
    line, = [w for w in r.warnings if "sound speed" in w]
    assert "precompression.force" in line and ";" not in line and "," not in line
    # a finite front velocity below the limit is kept
    assert not math.isfinite(r.v_g_front) or r.v_g_front <= guards.result_limits(scene).sound_speed


def test_the_same_preload_below_the_limit_reports_its_numbers():
    r, = run_scene(preloaded(0.1))
    assert r.status == "passed" and r.out_of_bounds == ()
    assert 0 < r.v_g < guards.result_limits(preloaded(0.1)).sound_speed


def test_both_engines_attach_the_scenes_limits():
    scene = preloaded(1e3)
    (m, traj), = trajectories(scene, members(scene), "reference")
    assert traj.limits == guards.result_limits(scene)


@pytest.mark.lammps
def test_the_lammps_engine_result_goes_through_the_same_bounds():
    scene = preloaded(1e3)
    r, = run_scene(scene, engine="lammps")
    assert r.status == "unphysical" and math.isnan(r.v_g) and "v_g" in r.out_of_bounds
    assert any("precompression.force" in w for w in r.warnings)


def test_a_delay_that_is_not_positive_is_nan_with_a_line_naming_the_key():
    """Probe 13 peaks before probe 2: the delay is negative; summarize used to report it
    as a number (v_g alone was NaN) with status passed."""
    t, v = pulses([5e-8 + 2e-7 * (14 - i) for i in range(15)])
    lim = guards.result_limits(preloaded(1e3))
    r = summarize(synthetic(v, t, limits=lim))
    assert r.wave_arrived
    assert math.isnan(r.dt_peak) and math.isnan(r.dt_front) and math.isnan(r.v_g)
    assert {"dt_peak", "dt_front"} <= set(r.out_of_bounds)
    assert r.status == "unphysical"
    line, = r.warnings
    assert "before probe 2" in line and "precompression.force" in line
    # the same record in order is reported
    t, v = pulses([5e-8 + 2e-7 * i for i in range(15)])
    ok = summarize(synthetic(v, t, limits=lim))
    assert ok.status == "passed" and ok.dt_peak == pytest.approx(22e-7, rel=1e-6)


def test_a_non_finite_energy_is_nan_with_a_line_naming_the_dashpot():
    # a dashpot 100 x faster than the collision (the validator refuses one much stiffer)
    stiff = scene_from_dict({"name": "stiff", "effects": ["hertz", "contact_damping"],
                             "damping": {"model": "viscoelastic", "eta": 3e13},
                             "striker": {"velocity": 0.1},
                             "integrator": {"method": "adaptive"}})
    lim = guards.result_limits(stiff)
    assert lim.nonfinite.startswith("damping.eta")
    # as a scene file writes it (YAML reads 3.0e13 as text; the validator as a number)
    from granchain.scenefile import parse_yaml
    raw = parse_yaml("name: stiff\neffects: [hertz, contact_damping]\ndamping: {model: "
                     "viscoelastic, eta: 3.0e13}\nintegrator: {method: adaptive}\n", "s.yaml")
    assert guards.result_limits(scene_from_dict(raw)).nonfinite.startswith("damping.eta ")
    t, v = pulses([5e-8 + 2e-7 * i for i in range(15)])
    e = np.ones((t.size, len(ENERGY_COLUMNS)))
    e[-1, 2] = np.inf
    r = summarize(synthetic(v, t, limits=lim, energy=e, status="nonfinite"))
    assert math.isnan(r.energy.hertz_potential) and math.isnan(r.energy.final_mechanical)
    assert "energy.hertz_potential" in r.out_of_bounds
    assert r.status == "nonfinite"
    line, = r.warnings
    assert "status nonfinite" in line and "damping.eta" in line


def test_the_check_is_idempotent_and_leaves_a_sound_result_alone():
    t, v = pulses([5e-8 + 2e-7 * i for i in range(15)])
    good = summarize(synthetic(v, t, limits=guards.result_limits(preloaded(0.1))))
    assert bounded(good, guards.result_limits(preloaded(0.1))) is good
    bad = dataclasses.replace(good, v_g=1e5)
    once = bounded(bad, guards.result_limits(preloaded(0.1)))
    assert math.isnan(once.v_g) and once.status == "unphysical"
    assert bounded(once, guards.result_limits(preloaded(0.1))) == once


def printed(scene, runs) -> str:
    out = io.StringIO()
    run_command._print_human(scene, runs, out)
    return out.getvalue()


def test_the_text_output_shows_a_timeout_the_json_has():
    """Fails on a build that printed a timed-out run's numbers as if it had passed."""
    scene = preloaded(0.1)
    r, = run_scene(scene)
    text = printed(scene, [dataclasses.replace(r, status="timeout")])
    assert "status timeout" in text and "time cap" in text
    assert "status" not in printed(scene, [r])


def test_a_run_without_a_measured_peak_says_what_its_status_means(one_run):
    """A run whose probes have no final peak prints the status with what it means, not a
    bare 'status passed' or 'status done' beside values that are n/a."""
    scene = scene_from_dict({"name": "short", "chain": {"n": 6}, "probes": [2, 6]})
    cut = dataclasses.replace(one_run, wave_arrived=False, not_final=(5, 6))
    for status, words in (("passed", "the wave had left the chain"),
                          ("done", "reached its end time")):
        line, = [ln for ln in printed(scene, [dataclasses.replace(cut, status=status)])
                 .splitlines() if "no measured peak" in ln]
        assert f"(status {status}: the run" in line and words in line, line


def test_the_text_output_of_an_impossible_run_shows_no_number(monkeypatch, tmp_path):
    """``granchain run`` of the 1e3 N chain: no v_g number, the status and the key."""
    (tmp_path / "s.yaml").write_text("name: s\n")
    monkeypatch.setattr(run_command, "load_scene", lambda *a, **k: preloaded(1e3))
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert cli.main(["run", str(tmp_path / "s.yaml"), "--no-progress"]) == 0
    text = out.getvalue()
    assert "v_g = n/a" in text and "status unphysical" in text
    assert "warning:" in text and "precompression.force" in text


@pytest.mark.lammps
def test_compare_says_when_a_guard_fired(monkeypatch):
    """Both engines' results go through the bounds; the comparison's text does not call
    values both engines set aside a pass."""
    from granchain import compare as cmpmod
    real = cmpmod.comparison_scene
    monkeypatch.setattr(cmpmod, "comparison_scene",
                        lambda s: dataclasses.replace(real(s), precompression=1e3))
    cmp = cmpmod.compare(preloaded(0.1))
    assert cmp.meta["status"] == {"reference": ["unphysical"], "lammps": ["unphysical"]}
    out = io.StringIO()
    run_command._print_comparison(cmp, out)
    text = out.getvalue()
    assert "status unphysical" in text and "precompression.force" in text
    assert text.splitlines()[-1] != "all tolerances met"


# ---------------------------------------------------------------------------------------
# the progress and log lines over many runs say which did not end as planned
# ---------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def one_run():
    r, = run_scene(scene_from_dict({"name": "short", "chain": {"n": 6}, "probes": [2, 6]}))
    return r


def test_a_study_batch_line_says_which_members_timed_out_or_were_unphysical(
        one_run, monkeypatch, capsys):
    """Fails on a build whose batch line said only 'N members in X s' (the table's status
    column alone said a member timed out)."""
    import pandas as pd
    from granchain import workflow as gw
    from granchain.workflow import run as wr
    from conftest import REPO
    _, P = gw.load_config(REPO / "config" / "config.yaml", "tiny")
    batch = gw.batches(P, "packed_sweep")[0]
    fake = [dataclasses.replace(one_run, status=s) for s in ("passed", "timeout", "unphysical")]
    monkeypatch.setattr(wr, "run_members", lambda *a, **k: fake)
    monkeypatch.setattr(wr, "member_rows", lambda *a, **k: pd.DataFrame({"x": [0]}))
    wr.run_batch(P, "packed_sweep", batch.name)
    err = capsys.readouterr().err
    assert "2 of 3 runs ended timeout (1), unphysical (1)" in err and "status" in err
    monkeypatch.setattr(wr, "run_members", lambda *a, **k: fake[:1])
    wr.run_batch(P, "packed_sweep", batch.name)
    assert "ended" not in capsys.readouterr().err


def test_the_accuracy_log_says_which_runs_timed_out(one_run, monkeypatch):
    """The accuracy study's log lines (a setting's errors, the reference's uncertainty)
    name the runs that did not end as planned, as its table's status column does."""
    from granchain.accuracy import harness
    monkeypatch.setattr(harness, "_run", lambda scene, setting, batch, memo=None: [
        dataclasses.replace(one_run, status="timeout" if setting.method == "rk4" else "done")
        for _ in range(batch)])
    lines = []
    harness.measure({"batch": 2, "repeats": 1, "gap_mean_nm": [], "methods": ["rk4", "adaptive"],
                     "steps_per_contact": [20], "tolerances": [1e-6]}, log=lines.append)
    rk4 = [ln for ln in lines if " rk4 " in f" {ln} " and "wall/chain" in ln]
    assert rk4 and all("2 of 2 runs ended timeout (2)" in ln for ln in rk4), lines
    assert not any("ended" in ln for ln in lines if "adaptive" in ln and "wall/chain" in ln)
    ref = [ln for ln in lines if ln.startswith("reference ")]
    assert ref and all("ended" not in ln for ln in ref)
    monkeypatch.setattr(harness, "_run", lambda scene, setting, batch, memo=None: [
        dataclasses.replace(one_run, status="stepfail" if setting.method == "adaptive"
                            else "done") for _ in range(batch)])
    lines.clear()
    harness.measure({"batch": 2, "repeats": 1, "gap_mean_nm": [], "methods": ["rk4"],
                     "steps_per_contact": [20], "tolerances": [1e-6]}, log=lines.append)
    ref = [ln for ln in lines if ln.startswith("reference ")]
    assert ref and all("2 of 2 runs ended stepfail (2)" in ln for ln in ref), lines
