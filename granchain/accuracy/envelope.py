"""Analysis of a measured accuracy-vs-cost table (pandas).

Errors against the reference (``rel_err``), the error envelope of each method
(``envelope``: the worst error of a setting and every finer one), the cheapest setting
meeting a tolerance (``cheapest``, ``cheapest_table``), the tightest verifiable tolerance
(``achievable``), and the cost model's rows (``model_from_table``). The packaged cost
model is looked up at run time by :mod:`granchain.costmodel`, which repeats ``envelope``,
``cheapest`` and ``achievable`` on its rows without pandas (tests/test_accuracy.py checks
that both agree).
"""
from __future__ import annotations

import itertools
import math

import numpy as np

from ..costmodel import DAMPED, MODEL_COLUMNS, SCENE_METHODS
from ..scenekeys import TOLERANCE_METHODS
from ..observables import ChainResult

# a study scene's name in the cost model's class 'damped': this and its undamped twin's
DAMPED_PREFIX = "damped-"


def rel_err(runs: list[ChainResult], ref: list[ChainResult], observable: str) -> float:
    """Largest |x / x_ref - 1| over the chains of the result field ``observable`` (one of
    ``harness.OBSERVABLES``); inf where a run lost what the reference has."""
    worst = 0.0
    for r, q in zip(runs, ref):
        x, x0 = getattr(r, observable), getattr(q, observable)
        if x0 is None or not math.isfinite(x0):
            continue
        if x is None or not math.isfinite(x):
            return math.inf
        worst = max(worst, abs(x / x0 - 1.0))
    return worst



def scene_class(name: str) -> str:
    """'damped', 'packed' or 'gapped' of a study scene name: the cost model keeps them
    apart (gaps cost accuracy; a contact force that depends on the closing speed costs
    the fixed-step methods their order)."""
    if name.startswith(DAMPED_PREFIX):
        return DAMPED
    return "packed" if name == "packed" else "gapped"


def _isnan(x) -> bool:
    return x is None or (isinstance(x, float) and math.isnan(x))


def _setting_key(row) -> tuple:
    spc, tol = row["steps_per_contact"], row["tolerance"]
    return (row["method"], None if _isnan(spc) else int(spc), None if _isnan(tol) else float(tol))


def _classes(table):
    if "scene_class" in table:
        return table["scene_class"]
    return table["scene"].map(scene_class)


def envelope(table, observable: str = "v_g", scene_class: str | None = None):
    """Per setting over the table's scenes (of ``scene_class`` only, if given): ``err``,
    the error on ``observable`` (``err_{observable}``, or ``balance_error`` for
    "balance"), its largest value over the scenes; ``envelope``, the largest ``err`` of
    this and every finer setting of the same method (more steps per contact time, tighter
    tolerance); ``wall_s_per_chain``, the mean over the scenes; ``ref_uncertainty``."""
    import pandas as pd
    col = "balance_error" if observable == "balance" else f"err_{observable}"
    unc_col = None if observable == "balance" else f"ref_uncertainty_{observable}"
    t = table.copy() if scene_class is None else table[_classes(table) == scene_class].copy()
    if "dt_s" not in t:                 # the cost model: dt lives as steps per contact
        t["dt_s"] = math.nan
    t["_key"] = [_setting_key(r) for _, r in t.iterrows()]
    agg = {"wall_s_per_chain": "mean", col: "max", "dt_s": "first"}
    if unc_col and unc_col in t:
        agg[unc_col] = "max"
    g = t.groupby("_key", sort=False).agg(agg).reset_index()
    g["method"] = [k[0] for k in g["_key"]]
    g["steps_per_contact"] = [k[1] for k in g["_key"]]
    g["tolerance"] = [k[2] for k in g["_key"]]
    g = g.rename(columns={col: "err"})
    g["ref_uncertainty"] = g[unc_col] if unc_col and unc_col in g else 0.0
    out = []
    for m, sub in g.groupby("method", sort=False):
        sub = sub.sort_values("tolerance" if m in TOLERANCE_METHODS else "steps_per_contact",
                              ascending=(m in TOLERANCE_METHODS))
        err = sub["err"].astype(float).fillna(math.inf).to_numpy()
        out.append(sub.assign(envelope=np.maximum.accumulate(err)))
    cols = ["method", "steps_per_contact", "tolerance", "dt_s", "wall_s_per_chain", "err",
            "envelope", "ref_uncertainty"]
    return pd.concat(out, ignore_index=True)[cols] if out else pd.DataFrame(columns=cols)


def cheapest(table, tol: float, observable: str = "v_g", *, methods=None,
             scene_class: str | None = None) -> dict | None:
    """The cheapest setting (least wall time per chain) whose error on ``observable`` is
    <= ``tol`` on every scene of the table (of ``scene_class``: 'packed' or 'gapped'),
    and stays so at every finer setting of its method (``envelope``). None if no setting
    does, or if ``tol`` is below the reference's own uncertainty (nothing that tight can be
    verified). Returns method, steps_per_contact (None for adaptive), tolerance (None for
    fixed steps), dt_s (None in the cost model), wall_s_per_chain, err, envelope."""
    env = envelope(table, observable, scene_class)
    if methods is not None:
        env = env[env["method"].isin(list(methods))]
    ok = env[(env["envelope"] <= tol) & (env["ref_uncertainty"].fillna(0.0) <= tol)]
    if ok.empty:
        return None
    best = ok.sort_values(["wall_s_per_chain", "method"], kind="mergesort").iloc[0]
    return {"method": str(best["method"]),
            "steps_per_contact": None if _isnan(best["steps_per_contact"]) else int(best["steps_per_contact"]),
            "tolerance": None if _isnan(best["tolerance"]) else float(best["tolerance"]),
            "dt_s": None if _isnan(best["dt_s"]) else float(best["dt_s"]),
            "wall_s_per_chain": float(best["wall_s_per_chain"]),
            "err": float(best["err"]), "envelope": float(best["envelope"])}


def achievable(table, observable: str = "v_g", *, methods=None, scene_class=None) -> float:
    """The tightest tolerance some setting meets that the reference can verify."""
    env = envelope(table, observable, scene_class)
    if methods is not None:
        env = env[env["method"].isin(list(methods))]
    if env.empty:
        return math.inf
    return max(float(env["envelope"].min()), float(env["ref_uncertainty"].fillna(0.0).max()))


def cheapest_table(table, tolerances, observables=("v_g", "v_g_front", "v_max_2")):
    """One row per (scenes, observable, tolerance): the cheapest setting (method 'none' if
    no setting meets it); scenes: all of the table's, the packed chain, the gapped ones,
    and the damped ones if the table has any."""
    import pandas as pd
    rows = []
    classes = (None, "packed", "gapped") + ((DAMPED,) if (_classes(table) == DAMPED).any() else ())
    for cls, obs, tol in itertools.product(classes, observables, tolerances):
        c = cheapest(table, float(tol), obs, scene_class=cls)
        head = {"scenes": cls or "all", "observable": obs, "tolerance_requested": float(tol)}
        if c is None:
            c = {"method": "none", "steps_per_contact": None, "tolerance": None, "dt_s": None,
                 "wall_s_per_chain": None, "err": None, "envelope": None}
        rows.append({**head, **{k: (math.nan if v is None else v) for k, v in c.items()}})
    return pd.DataFrame(rows)



def model_from_table(table):
    """One row per (scene class, setting of the reference engine): the worst error over the
    class's scenes, their mean wall time per chain; dt as steps per contact time. The
    damped class's errors are the worst over every scene: a damped chain at restitution
    1 is an undamped one."""
    t = table[table["method"].isin(SCENE_METHODS)].copy()
    t["scene_class"] = _classes(t)
    t["_setting"] = [_setting_key(r) for _, r in t.iterrows()]
    t["_key"] = [(c,) + k for c, k in zip(t["scene_class"], t["_setting"])]
    errs = list(MODEL_COLUMNS[5:])
    agg = {c: "max" for c in errs}
    agg["wall_s_per_chain"] = "mean"
    g = t.groupby("_key", sort=False).agg(agg).reset_index()
    worst = t.groupby("_setting", sort=False)[errs].max()
    for i in np.flatnonzero([k[0] == DAMPED for k in g["_key"]]):
        g.loc[g.index[i], errs] = worst.loc[[g["_key"].iloc[i][1:]], errs].to_numpy()[0]
    for i, c in enumerate(("scene_class", "method", "steps_per_contact", "tolerance")):
        g[c] = [k[i] for k in g["_key"]]
    return g[list(MODEL_COLUMNS)]

