"""The integrator setting an inference simulates its grid with: chosen from the accuracy
the data need, unless the base scene gives its own.

A simulated value's integration error adds to the measurement's noise in the likelihood.
It is negligible when it is a small fraction of the smallest error the rows state: the
inference asks method auto (``runplan.plan_run``: the cheapest setting of the packaged
cost model whose measured relative error on v_g, with auto's margin, meets a tolerance)
for a tolerance of ``ACCURACY_FRACTION`` x the smallest stated relative error, the
smallest of ``dt_err_s`` / timing over the rows and, when the peaks are fitted too,
``vmax_err_m_s`` / each peak. A relative error of the timing is one of v_g (v_g = (p2 -
p1)(2R + gbar) / dt), the observable auto bounds. Auto does not bound the peaks: their
errors at the chosen setting are measured (tests/test_inference_setting.py; on the
shipped joint example, whose timing's error sets the tolerance, within half of their own
fraction), and a file whose peaks state a smaller relative error than its timing asks
auto for that tolerance on v_g all the same.

- A base scene that gives no integrator, or ``method: auto`` without a tolerance, gets
  this setting (``source`` "data"); one that states no error on any row gets auto at its
  default tolerance (``scenekeys.DEFAULT_TOLERANCE``, ``source`` "default").
- A base scene that gives its integrator (a method other than auto, a step, or auto with
  its own tolerance) keeps it (``source`` "scene").

One setting for every node of the grid and every striker speed
(``plan_run(..., per_speed=False)``): one kernel to compile, and the same integration at
every node, so a realisation's values stay smooth across the grid. It is chosen for the
base scene's mean gap (a placeholder the grid replaces), or for ``CHOICE_GAP`` when that
is 0: auto rates packed and gapped chains apart, and the grid's nodes are gapped.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..errors import GranchainError, SceneError
from ..scene import Scene
from .measurements import Measurements

# the simulation's relative error asked for, as a fraction of the smallest stated one
ACCURACY_FRACTION = 0.1
# the mean gap auto chooses at when the base scene's placeholder is 0 (the chapter's law
# completed with mean 0): the grid's nodes are gapped chains, which auto's cost model
# rates apart from packed ones; the shipped examples' placeholder
CHOICE_GAP = 50e-9
_GIVEN = ("integrator.dt", "integrator.tolerance")


def smallest_error(meas: Measurements, peaks: bool) -> tuple[float, str | None, int | None]:
    """(relative error, column, file line) of the smallest stated relative error of the
    rows: ``dt_err_s`` over the row's timing and, with ``peaks``, ``vmax_err_m_s`` over
    each of its peaks; (NaN, None, None) when no row states an error (> 0)."""
    best = (math.inf, None, None)
    cand = [(meas.err / meas.t, "dt_err_s")]
    if peaks and meas.vmax_1 is not None and meas.vmax_2 is not None:
        cand += [(meas.peak_err / meas.vmax_1, "vmax_err_m_s"),
                 (meas.peak_err / meas.vmax_2, "vmax_err_m_s")]
    for rel, col in cand:
        rel = np.where(np.isfinite(rel) & (rel > 0), rel, np.inf)
        k = int(np.argmin(rel))
        if rel[k] < best[0]:
            best = (float(rel[k]), col, int(meas.lines[k]))
    return best if math.isfinite(best[0]) else (math.nan, None, None)


def scene_gives_integrator(base: Scene) -> bool:
    """Does the base scene give its own integrator setting (a method other than auto, a
    step, or auto with its tolerance)?"""
    if any(k in base.given for k in _GIVEN):
        return True
    return "integrator.method" in base.given and base.auto_tolerance is None \
        and base.method != "auto"


def choose_setting(base: Scene, meas: Measurements, peaks: bool,
                   source: str = "") -> tuple[Scene, dict]:
    """The base scene with its grid's integrator setting resolved (one setting for every
    striker speed; module doc), and the record of the choice: ``method``, ``dt_s``,
    ``tolerance`` (the method's own; None for a fixed step), ``v_g_tolerance`` (what auto
    was asked; None when the scene's setting is not auto's), ``source`` ("data", "default"
    or "scene"), ``fraction``, ``smallest_relative_error`` and ``set_by`` (the column and
    line that set it; None without one), ``reason`` (one sentence). The returned scene
    keeps the base scene's ``given``, so choosing again changes nothing. A tolerance
    tighter than auto can deliver is one GranchainError naming the column and line."""
    from ..runplan import describe_auto, plan_run
    rel, col, line = smallest_error(meas, peaks)
    rec = {"fraction": ACCURACY_FRACTION,
           "smallest_relative_error": None if math.isnan(rel) else rel,
           "set_by": None if col is None else {"column": col, "line": line}}
    if scene_gives_integrator(base):
        scene = plan_run(base, per_speed=False).scene
        how = describe_auto(scene) if scene.auto_tolerance is not None else _describe(scene)
        rec.update(source="scene", v_g_tolerance=scene.auto_tolerance,
                   reason=f"the base scene's integrator ({how})")
    else:
        from ..scenekeys import DEFAULT_TOLERANCE, DEFAULTS
        tol = None if math.isnan(rel) else min(ACCURACY_FRACTION * rel, 0.1)
        ask = DEFAULT_TOLERANCE["auto"] if tol is None else tol
        try:
            # the derived scene keeps the base scene's given keys: the step and tolerance
            # set here are auto's to choose, not the user's
            change = {"integrator": {"method": "auto", "tolerance": ask,
                                     "dt": DEFAULTS["integrator"]["dt"]}}
            if base.gap_mean == 0.0:
                change["gaps"] = {"mean": CHOICE_GAP}
            auto = dataclasses.replace(base.derive(change), given=base.given)
            scene = plan_run(auto, per_speed=False).scene
        except SceneError as exc:
            if tol is None or exc.field != "integrator.tolerance":
                raise
            raise GranchainError(
                f"{source}row at line {line}, column {col!r}: a stated relative error of "
                f"{rel:.3g} asks the simulation for {ask:.3g} on v_g ({ACCURACY_FRACTION:g} "
                "of it), finer than method auto can deliver; check the error's units, or "
                "give the base scene its own integrator (integrator.method with its dt or "
                "tolerance)") from None
        scene = dataclasses.replace(scene, given=base.given)
        if tol is None:
            why = (f"auto at its default tolerance {ask:g} on v_g: the rows state no error "
                   "(dt_err_s" + (", vmax_err_m_s" if peaks else "") + ")")
        else:
            why = (f"auto at tolerance {ask:.3g} on v_g: {ACCURACY_FRACTION:g} x the "
                   f"smallest stated relative error, {rel:.3g} ({col} at line {line})")
        rec.update(source="default" if tol is None else "data", v_g_tolerance=ask,
                   reason=f"{why} -> {_describe(scene)}")
    rec.update(method=scene.method, dt_s=float(scene.dt),
               tolerance=scene.tolerance if scene.method in ("adaptive", "event") else None)
    order = ("method", "dt_s", "tolerance", "v_g_tolerance", "source", "fraction",
             "smallest_relative_error", "set_by", "reason")
    return scene, {k: rec[k] for k in order}


def _describe(scene: Scene) -> str:
    """'rk4, dt 7.17e-08 s' or 'event, tolerance 0.0001'."""
    if scene.method in ("adaptive", "event"):
        return f"{scene.method}, tolerance {scene.tolerance:g}"
    return f"{scene.method}, dt {scene.dt:.3g} s"
