"""The plasticity study (granchain.workflow.question_scenes): its scenes (the elastic chain
and Thornton's contacts at factors of each material's library p_y, the base effects less
those the law does not act with), its reductions (the p_y at which v_max,1 is the measured
0.57 v_s, the exponent of v_max,1(v_s)) on tables whose answers are known, and its thesis
rows on the tiny preset's chains."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from granchain import reductions
from granchain import workflow as gw
from granchain.errors import GranchainError
from granchain.materials import library
from granchain.thesis import rows as thesis_rows
from granchain.thesis.rows.common import packed_chain

CONFIG = Path(__file__).resolve().parents[1] / "config" / "config.yaml"


def _preset(name="tiny"):
    return gw.load_config(CONFIG, name)[1]


def test_plasticity_scenes_are_the_elastic_chain_and_each_factor_of_the_library_py():
    P = _preset("default")
    spec = P["studies"]["plasticity"]
    scenes = gw.study_scenes(P, "plasticity")
    lib = library()
    factors = spec["yield_pressure_factor"]
    assert len(scenes) == len(P["materials"]) * (1 + len(factors))
    base = set(P["base"]["effects"]) - {"particle_friction", "rolling_friction"}
    assert "particle_friction" in P["base"]["effects"]      # so the removal is tested
    for ss in scenes:
        st = dict(ss.setting)
        sc = ss.scene
        assert sc.method == spec["method"] and list(sc.striker_velocities) == spec["v_striker"]
        if math.isinf(st["yield_pressure_Pa"]):
            assert st["plasticity_model"] == "none"
            assert sc.effects == frozenset(base)
        else:
            assert sc.effects == frozenset(base | {"plastic_contact"})
            assert st["plasticity_model"] == "thornton"
            f = st["yield_pressure_Pa"] / lib[ss.material].yield_pressure
            assert any(f == pytest.approx(x, rel=1e-12) for x in factors)
            assert sc.setting("plastic_contact").yield_pressure == st["yield_pressure_Pa"]
        assert ss.meta["yield_pressure_Pa"] == st["yield_pressure_Pa"]


def test_a_study_material_without_a_yield_pressure_is_refused_in_one_line():
    cfg = gw.read_config(CONFIG, "tiny")
    cfg["presets"]["tiny"]["studies"]["plasticity"]["materials"] = ["brass"]
    with pytest.raises(GranchainError) as err:
        gw.Plan.build(cfg)
    msg = str(err.value)
    assert "\n" not in msg and "'brass' has no yield_pressure" in msg
    assert msg.startswith("invalid configuration at 'presets.tiny.studies.plasticity'")
    assert "ss316" in msg and "ss440c" in msg


def _table(v1_of, vs=(0.01, 0.1, 1.0), pys=(1e7, 1e8, 1e9, math.inf), chains=3):
    """A plasticity table whose chains' v_max,1 / v_s is v1_of(p_y, v_s) (spread +-1% over
    the chains, so the median is the value), v_max,2 = 0.8 v_max,1."""
    rows = []
    for py in pys:
        for v in vs:
            for k, s in enumerate(np.linspace(-0.01, 0.01, chains)):
                v1 = v1_of(py, v) * (1 + s) * v
                rows.append({"material": "ss316", "v_striker_m_s": v, "gap_mean_nm": 0.0,
                             "realisation": k, "v_max_1_m_s": v1, "v_max_2_m_s": 0.8 * v1,
                             "v_max_ratio": 0.8, "v_g_m_s": 400.0, "wave_arrived": True,
                             "plasticity_model": "none" if math.isinf(py) else "thornton",
                             "yield_pressure_Pa": py})
    return pd.DataFrame(rows)


def test_the_match_is_the_py_where_the_median_crosses_the_measured_peak_in_log_py():
    """v_max,1 / v_s = 0.5 + 0.05 log10(p_y / 1e7) (elastic: 0.7) crosses 0.57 at
    log10(p_y / 1e7) = 1.4, p_y = 10^8.4 Pa; the interval's ends 0.48 and 0.66 at
    10^6.6 (below the study: NaN) and 10^10.2 (above it: NaN, the elastic end is not
    interpolated)."""
    df = _table(lambda py, v: 0.7 if math.isinf(py) else 0.5 + 0.05 * math.log10(py / 1e7))
    m = reductions.plasticity_match(df)
    assert len(m) == 3
    for _, r in m.iterrows():
        assert r["py_v1"] == pytest.approx(10 ** 8.4, rel=1e-9)
        assert math.isnan(r["py_v1_lo"]) and math.isnan(r["py_v1_hi"])
        assert r["v1_elastic"] == pytest.approx(0.7, rel=1e-12)
        assert r["v2"] == pytest.approx(0.8 * 0.57, rel=1e-9)
        assert r["py_min"] == pytest.approx(1e7) and r["n_py"] == 3


def test_the_exponent_of_vmax1_is_one_for_a_linear_chain_and_less_for_a_yielding_one():
    """v_max,1 = 0.7 v_s (elastic) and 0.6 v_s (v_s / 0.1)^-0.05 (p_y = 1e8): b = 1 and
    0.95."""
    df = _table(lambda py, v: 0.7 if math.isinf(py) else 0.6 * (v / 0.1) ** -0.05,
                pys=(1e8, math.inf))
    e = reductions.plasticity_exponents(df).set_index("yield_pressure_Pa")
    assert e.loc[math.inf, "b"] == pytest.approx(1.0, abs=1e-12)
    assert e.loc[1e8, "b"] == pytest.approx(0.95, abs=1e-12)
    assert e.loc[1e8, "a"] == pytest.approx(0.6 * 0.1 ** 0.05, rel=1e-9)


@pytest.fixture(scope="module")
def tiny_rows():
    """The tiny preset's plasticity study, run on the reference engine, and its packed
    sweep's 440C chain for the rows' common part."""
    from granchain import tables as gtables
    from granchain.simulate import run_scene
    P = _preset("tiny")
    out = {}
    for study in ("plasticity", "packed_sweep"):
        rows = []
        for ss in gw.study_scenes(P, study):
            rows += [gtables.member_row(ss.meta, r, ss.scene.n) for r in run_scene(ss.scene)]
        out[study] = gtables.study_table(rows, gw.study_scenes(P, study)[0].scene.n)
    return out


def test_yielding_takes_off_the_peak_more_at_a_lower_py_and_a_higher_speed(tiny_rows):
    """On the tiny preset's chains: at each speed v_max,1 / v_s rises with p_y up to the
    elastic chain's (equal to it where the contacts never reach p_y); 316 at its library
    p_y (464 MPa) yields at 0.02 m/s already, and
    loses more of v_max,1 / v_s at 0.2 m/s than at 0.02 m/s (Thornton's e falls with the
    speed); 440C at its library p_y stays nearly elastic at 0.02 m/s."""
    c = reductions.plasticity_curves(tiny_rows["plasticity"])
    for (mat, vs), g in c.groupby(["material", "v_striker_m_s"]):
        v1 = g.sort_values("yield_pressure_Pa")["v1_median"].to_numpy()
        # a p_y the contacts never reach is the elastic chain (440C's library p_y at low
        # speed): no loss, the same peak
        assert np.all(np.diff(v1) >= 0) and v1[0] < v1[-1], (mat, vs, v1)
    lib = library()

    def v1(mat, py, vs):
        r = c[(c["material"] == mat) & (c["v_striker_m_s"] == vs)
              & np.isclose(c["yield_pressure_Pa"], py, rtol=1e-12)]
        return float(r["v1_median"].iloc[0])
    loss = {vs: 1 - v1("ss316", lib["ss316"].yield_pressure, vs) / v1("ss316", math.inf, vs)
            for vs in (0.02, 0.2)}
    assert 0.01 < loss[0.02] < loss[0.2]
    assert 1 - v1("ss440c", lib["ss440c"].yield_pressure, 0.02) \
        / v1("ss440c", math.inf, 0.02) < 1e-3


def test_plasticity_rows_quote_the_reductions(tiny_rows):
    pk = packed_chain(tiny_rows["packed_sweep"])
    rows = {r["id"]: r for r in thesis_rows.plasticity_rows(pk, tiny_rows["plasticity"])}
    assert set(rows) == {f"plast_{w}_{m}" for w in ("vmax1_library", "py_match", "exponent")
                         for m in ("ss316", "ss440c")}
    c = reductions.plasticity_curves(tiny_rows["plasticity"])
    lib = library()["ss316"].yield_pressure
    # the tiny preset's speeds are 0.02 and 0.2: 0.2 is nearest 0.1 in log
    want = c[(c["material"] == "ss316") & (c["v_striker_m_s"] == 0.2)
             & np.isclose(c["yield_pressure_Pa"], lib, rtol=1e-12)]["v1_median"].iloc[0]
    assert rows["plast_vmax1_library_ss316"]["project_value"] == pytest.approx(want, rel=1e-12)
    e = reductions.plasticity_exponents(tiny_rows["plasticity"])
    for mat in ("ss316", "ss440c"):
        r = rows[f"plast_exponent_{mat}"]
        assert r["chapter_value"] == 1.0
        assert any(r["project_value"] == pytest.approx(b, rel=1e-12)
                   for b in e[e["material"] == mat]["b"])
        m = rows[f"plast_py_match_{mat}"]
        assert m["unit"] == "Pa" and "per speed" in m["reason"]
