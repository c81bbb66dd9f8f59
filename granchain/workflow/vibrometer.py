"""The vibrometer study: the chapter's instrument applied to simulated chains.

One job. Each chain (material x mean gap x striker speed x realisation, the scenes of
:func:`.studies.vibrometer_scenes`) is simulated once, keeping its probes' velocity
histories; the recording (``granchain.vibrometer``) is post-processing, so every
instrument setting (filter x bandwidth, :func:`.studies.vibrometer_settings`) filters the
same trajectory, nothing is re-simulated per bandwidth.

Outputs:
- ``tables/vibrometer.csv``: one row per (chain, filter, bandwidth) with the true and the
  recorded v_max,1, v_max,2, dt (peak to peak) and dt_front (half-peak fronts), their
  ratios measured/true and the delay biases measured - true (NaN with the probe in
  ``measured_not_final`` when a recorded peak is not final; NaN, status ``unphysical`` and
  a line in ``warnings`` when a true or recorded value leaves its physical bounds,
  ``observables.bounded``); ``VIB_COLUMNS``;
- ``tables/vibrometer.provenance.json``;
- ``timing/vibrometer.csv``;
- ``traces/vibrometer_<material>.npz``: the packed chain at the speed nearest 0.1 m/s,
  true and recorded probe velocities at the bandwidth nearest the chapter's 2.5 MHz, each
  filter (the counterpart of the chapter's Fig. 5.2a; ``TRACE_KEYS``).
"""
from __future__ import annotations

import dataclasses
import math
import sys
import time

import numpy as np
import pandas as pd

from .. import columns, tables
from ..errors import GranchainError
from ..gaps import members as scene_members
from ..vibrometer import extract, measure, needs_trace, record
from ..observables import bounded, probe_span, status_summary, summarize
from ..scenekeys import MEASUREMENT_DEFAULTS
from ..simulate import trajectories
from .studies import VIBROMETER, StudyScene, vibrometer_scenes, vibrometer_settings

CHAPTER_BANDWIDTH_HZ = float(MEASUREMENT_DEFAULTS["bandwidth_hz"])
TRACE_SPEED = 0.1          # m/s: the trace of Fig. 5.2a's counterpart (chapter Fig. 5.1a's)

# the table's columns, in order: their documentation (granchain.columns) is the one list;
# run_vibrometer's table takes its columns from the rows, so a row that leaves the list
# shows in the table
VIB_COLUMNS = tuple(columns.VIBROMETER)
TRACE_KEYS = ("t_s", "v_m_s", "probes", "v_striker_m_s", "material", "bandwidth_hz",
              "sampling_rate_hz", "order", "filters", "t_rec_s", "vmax_true_m_s",
              "t_peak_true_s")      # and per filter F: v_rec_F_m_s, vmax_rec_F_m_s, t_peak_rec_F_s


def _ratio(a: float, b: float) -> float:
    return a / b if math.isfinite(a) and math.isfinite(b) and b > 0 else math.nan


def _rows(ss: StudyScene, settings, m, traj) -> list[dict]:
    sc = ss.scene
    s = summarize(traj, sc.probes)
    final = [s.final[p - 1] for p in sc.probes]
    out = []
    for st in settings:
        # the recorded values go through the run's physical bounds, as the run table's do
        # (simulate.run_scene): an impossible one is NaN, named in the warnings, status
        # unphysical
        rec = measure(traj, sc.probes, st, key=(m.index,), true_final=final)
        r = bounded(dataclasses.replace(s, **rec.result_fields(sc.probes)), traj.limits)
        out.append({
            "study": VIBROMETER, "material": ss.material,
            "gap_distribution": sc.gap_distribution, "gap_mean_nm": ss.gap_mean_nm,
            "v_striker_m_s": float(m.v_striker), "realisation": int(m.realisation),
            "seed": int(sc.gap_seed), "scene_hash": sc.hash,
            "method": traj.info.method, "dt_s": float(traj.info.dt),
            "status": r.status, "wave_arrived": bool(s.wave_arrived),
            "filter": st.filter, "order": int(st.order), "bandwidth_hz": st.bandwidth_hz,
            "sampling_rate_hz": st.sampling_rate_hz,
            "v_max_1_m_s": s.v_max_1, "v_max_2_m_s": s.v_max_2, "dt_peak_s": s.dt_peak,
            "dt_front_s": s.dt_front, "v_g_m_s": s.v_g,
            "v_max_1_measured_m_s": r.v_max_1_measured,
            "v_max_2_measured_m_s": r.v_max_2_measured,
            "dt_peak_measured_s": r.dt_peak_measured,
            "dt_front_measured_s": r.dt_front_measured, "v_g_measured_m_s": r.v_g_measured,
            "measured_not_final": ";".join(str(p) for p in r.measured_not_final),
            "v_max_1_measured_over_true": _ratio(r.v_max_1_measured, s.v_max_1),
            "v_max_2_measured_over_true": _ratio(r.v_max_2_measured, s.v_max_2),
            "dt_peak_bias_s": r.dt_peak_measured - s.dt_peak,
            "dt_front_bias_s": r.dt_front_measured - s.dt_front,
            "warnings": ";".join(r.warnings),
        })
    return out


def _trace(ss: StudyScene, settings, m, traj) -> dict:
    """The Fig. 5.2a counterpart: true and recorded probe velocities, each filter at the
    bandwidth nearest the chapter's."""
    sc = ss.scene
    bws = sorted({st.bandwidth_hz for st in settings})
    bw = bws[int(np.argmin([abs(math.log(b / CHAPTER_BANDWIDTH_HZ)) for b in bws]))]
    chosen = [st for st in settings if st.bandwidth_hz == bw]
    cols = [p - 1 for p in sc.probes]
    out = {"t_s": traj.t, "v_m_s": traj.v[:, cols], "probes": np.array(sc.probes),
           "v_striker_m_s": np.float64(m.v_striker), "material": np.str_(ss.material),
           "bandwidth_hz": np.float64(bw),
           "sampling_rate_hz": np.float64(chosen[0].sampling_rate_hz),
           "order": np.int64(chosen[0].order),
           "filters": np.array([st.filter for st in chosen])}
    s = summarize(traj, sc.probes)
    out["vmax_true_m_s"] = np.array([s.v_max[c] for c in cols])
    out["t_peak_true_s"] = np.array([s.t_peak[c] for c in cols])
    _, span = probe_span(traj, sc.probes)
    for st in chosen:
        rec = record(traj.t, traj.v[:, cols], st, key=(m.index,))
        got = extract(rec.t, rec.v, span, [s.final[c] for c in cols])
        out["t_rec_s"] = rec.t
        out[f"v_rec_{st.filter}_m_s"] = rec.v
        out[f"vmax_rec_{st.filter}_m_s"] = np.array(got.v_max)
        out[f"t_peak_rec_{st.filter}_s"] = np.array(got.t_peak)
    return out


def run_vibrometer(preset: dict) -> tuple[pd.DataFrame, dict[str, dict], pd.DataFrame]:
    """(the study's table, {material: trace}, timing rows)."""
    rows, traces, timing = [], {}, []
    for ss in vibrometer_scenes(preset):
        sc = ss.scene
        # The recording needs the probes' whole velocity histories: the study's scenes
        # carry a measurement block, so needs_trace(sc) is True; an engine that keeps
        # full traces only on request gets it from there.
        trace = needs_trace(sc)
        settings = vibrometer_settings(preset, ss)
        mem = scene_members(sc)
        t0 = time.perf_counter()
        trace_speed = min(sc.striker_velocities, key=lambda v: abs(math.log(v / TRACE_SPEED)))
        steps = 0
        statuses = []
        for m, traj in trajectories(sc, mem, "reference"):
            if not trace:
                raise GranchainError(f"{sc.name}: the vibrometer study needs traces")
            steps += int(traj.steps)
            rows += _rows(ss, settings, m, traj)
            statuses += [r["status"] for r in rows[-len(settings):]]
            if (ss.gap_mean_nm == 0 and m.v_striker == trace_speed
                    and ss.material not in traces):
                traces[ss.material] = _trace(ss, settings, m, traj)
        wall = time.perf_counter() - t0
        timing.append({"study": VIBROMETER, "engine": "reference", "batch": sc.name,
                       "scene_hash": sc.hash, "members": len(mem), "steps": steps,
                       "wall_s": wall, "wall_per_member_s": wall / max(1, len(mem))})
        ended = status_summary(statuses)
        print(f"[granchain] {VIBROMETER}: {sc.name} {len(mem)} chains x {len(settings)} "
              f"instrument settings in {wall:.2f} s" + (
                  f"; {ended} (the table's status and warnings columns say which)"
                  if ended else ""), file=sys.stderr, flush=True)
    df = pd.DataFrame(rows) if rows else pd.DataFrame(columns=list(VIB_COLUMNS))
    for c in ("realisation", "seed", "order"):
        df[c] = df[c].astype("int64")
    return df, traces, tables.timing_table(timing)


def write_vibrometer(preset_name: str, preset: dict, out_table, out_provenance, out_timing,
                     trace_paths: dict[str, str]) -> pd.DataFrame:
    """Run the study and write its table, provenance, timing and traces."""
    df, traces, timing = run_vibrometer(preset)
    for mat, path in trace_paths.items():
        tables.write_npz(path, **traces[mat])
    spec = preset["studies"][VIBROMETER]
    tables.write_csv(timing, out_timing)
    tables.write_provenance(
        out_provenance, preset=preset_name, study=VIBROMETER,
        config_hash=tables.config_hash(preset),
        scene_hashes={ss.scene.name: ss.scene.hash for ss in vibrometer_scenes(preset)},
        seeds=sorted({int(s) for s in df["seed"]}), rows=int(len(df)),
        instrument={"filters": list(spec["filters"]), "order": int(spec["order"]),
                    "bandwidth_hz": sorted(float(b) for b in spec["bandwidth_hz"]),
                    "sampling_rate_hz": float(spec["sampling_rate_hz"]),
                    "noise_rms_m_s": 0.0},
        recording="granchain.vibrometer: resampled onto the digitiser grid, causal "
                  "analog prototype (bilinear, bandwidth pre-warped), same filter on both "
                  "probes; peaks refined as granchain.observables.peak")
    tables.write_csv(df, out_table)
    return df


def trace_materials(preset: dict) -> list[str]:
    """Materials with a packed vibrometer scene (each gets a Fig. 5.2a trace)."""
    return list(dict.fromkeys(ss.material for ss in vibrometer_scenes(preset)
                              if ss.gap_mean_nm == 0))
