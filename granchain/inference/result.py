"""What both fits report besides their parameters: the common base of
:class:`~granchain.inference.gapfit.Inference` and
:class:`~granchain.inference.jointfit.JointInference` (their JSON document) and the fields
both take from the grid, the base scene and the data (:func:`shared_fields`)."""
from __future__ import annotations

import dataclasses
from typing import ClassVar

from ..scene import Scene


class FitResult:
    """The common base of the fits' results (frozen dataclasses, SI units; NaN where not
    measured, with ``flags``). Both have the fields of :func:`shared_fields`, the
    posterior's mean gap, median and interval (``gap_mean_m``, ``ci95_m``), the Eq. 5.4
    readings (``eq54_gap_m``, ``eq54_gap_bound_m``, ``eq54_gap_rows_m``), ``method``,
    ``interp_rel_error`` and ``flags``; each declares them in the order of its JSON
    document, which interleaves them with its own (the documents keep the order they had
    before the base existed)."""
    # fields left out of the JSON document: the posterior's arrays and the grid
    HIDDEN: ClassVar[tuple[str, ...]] = ()

    def to_json(self) -> dict:
        """The result as a JSON document: every field but ``HIDDEN``, tuples as lists."""
        d = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)
             if f.name not in self.HIDDEN}
        for k, v in d.items():
            if isinstance(v, tuple):
                d[k] = list(v)
        return d


def shared_fields(base: Scene, src: dict, meas, grid, check, chosen: dict | None = None
                  ) -> dict:
    """The fields both results take from the completed base scene ``base`` and its sources
    ``src`` (``grid.complete_base``), the measurements ``meas``, the grid (a ``Grid`` or a
    ``JointGrid``), the model check ``check`` (``modelcheck.ModelCheck``) and the choice of
    integrator ``chosen`` (``setting.choose_setting``; :func:`integrator_record`)."""
    return dict(
        n_simulated=grid.n_chains, n_simulated_now=grid.simulated,
        n_unmeasured=grid.unmeasured(meas.column), gap_law=_law(base, grid),
        timing_column=meas.column, realisations=grid.realisations,
        gap_grid_m=(float(grid.gaps[0]), float(grid.gaps[-1]), int(grid.gaps.size)),
        speeds_m_s=tuple(float(v) for v in grid.speeds), gap_law_source=src["gap_law"],
        speeds_source=src["speeds"], rows=len(meas), chains=len(meas.groups),
        scene=base.name, scene_hashes=grid.hashes, data_outside_model=check.to_json(),
        integrator=integrator_record(grid, chosen), grid=grid)


def integrator_record(grid, chosen: dict | None) -> dict:
    """The integrator the grid's chains ran with (``grid.setting``), and why: the record
    ``chosen`` (``setting.choose_setting``) when the grid ran that setting; else the
    grid's own setting with ``source`` "grid" (a grid simulated before the fit and given
    to it: the choice made for these data is not what it ran) and no reason of the data."""
    none = {"method": None, "dt_s": None, "tolerance": None, "v_g_tolerance": None}
    got = grid.setting if getattr(grid, "setting", None) is not None else none
    # a node scene derived from a resolved scene keeps its setting, not auto's request
    if chosen is not None and all(chosen[k] == got[k] for k in ("method", "dt_s", "tolerance")):
        return dict(chosen)
    return dict(got, source="grid", fraction=None, smallest_relative_error=None, set_by=None,
                reason="the setting of the grid given to the fit" if got["method"] is not None
                else "not known: the grid given to the fit does not say")


def _law(base: Scene, grid=None) -> str:
    """The base scene's gap law, as the results name it, with the key contacts' prior of
    a designed grid (``gapdesign.prior_weights``)."""
    law = ("uniform on [0, 2 mean], i.i.d. per contact" if base.gap_distribution == "uniform"
           else "exponential with the given mean, i.i.d. per contact")
    if grid is not None and grid.weights is not None and grid.key_prior == "robust":
        law += ("; the contacts beside the probes with a heavier prior toward contact (half "
                "the law, half a Beta(1/3, 1) on the quantile: granchain.gapdesign)")
    return law
