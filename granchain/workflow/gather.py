"""Gathering: a study's batch tables -> its table (CSV and its Parquet copy), summary,
provenance and timing.

Pure table work (the batches' rows are complete): concatenate, put the rows in table
order, check every member is there exactly once, and write.
"""
from __future__ import annotations

import pandas as pd

from .. import tables
from ..errors import GranchainError
from .config import FIELD_STUDIES
from .studies import ENGINE_ORDER, StudyScene, study_scenes


def _order(df: pd.DataFrame, scenes: list[StudyScene]) -> pd.DataFrame:
    """Table order: scene (config order), engine, striker speed (config order), realisation."""
    by_hash = {ss.scene.hash: ss for ss in scenes}
    unknown = set(df["scene_hash"]) - set(by_hash)
    if unknown:
        raise GranchainError(f"batch tables hold scenes {sorted(unknown)} that the configuration "
                             "does not define; delete the study's work folder and re-run")
    si = df["scene_hash"].map(lambda h: by_hash[h].index)
    vi = [by_hash[h].scene.striker_velocities.index(v)
          for h, v in zip(df["scene_hash"], df["v_striker_m_s"])]
    ei = df["engine"].map(ENGINE_ORDER.index)
    keyed = df.assign(_s=si.to_numpy(), _e=ei.to_numpy(), _v=vi, _r=df["realisation"].to_numpy())
    keyed = keyed.sort_values(["_s", "_e", "_v", "_r"], kind="stable")
    dup = keyed.duplicated(["_s", "_e", "_v", "_r"])
    if dup.any():
        raise GranchainError("batch tables overlap (a member appears twice); delete the "
                             "study's work folder and re-run")
    return keyed.drop(columns=["_s", "_e", "_v", "_r"]).reset_index(drop=True)


def _packed_engines(scenes: list[StudyScene]) -> str:
    """The engine(s) of a study's packed references, as the provenance says it."""
    names = {"reference": "reference engine", "lammps": "LAMMPS engine"}
    return " and ".join(names[e] for e in ENGINE_ORDER
                        if any(ss.packed_engine == e for ss in scenes))


def study_provenance(preset_name: str, preset: dict, study: str, scenes: list[StudyScene],
                     df: pd.DataFrame) -> dict:
    """What a study's provenance JSON records besides the environment."""
    eq54 = ("v_g_bound_eq54_m_s: (2R + gbar)/v = 2R/v_g_packed + gbar/v_s with gbar the "
            "row's mean gap between the probes and v_g_packed the arrival-time group "
            f"velocity of the packed chain ({_packed_engines(scenes)}, same scene)"
            if any(ss.eq54 for ss in scenes) else
            "v_g_bound_eq54_m_s: NaN, not computed (" + (
                "packed chains on an end wall: the bound is about gaps" if study in FIELD_STUDIES
                else "spheres of unequal radii or damped contacts: the bound is about elastic "
                "chains of equal spheres") + ")")
    walled = {}
    if any(ss.scene.wall is not None for ss in scenes):
        walled["walls"] = {ss.scene.name: {"wall": ss.scene.wall.name,
                                           "precompression_N": ss.scene.precompression,
                                           "n": ss.scene.n, "probes": list(ss.scene.probes)}
                           for ss in scenes}
    settings = {}
    if any(ss.setting for ss in scenes):
        settings["settings"] = {ss.scene.name: dict(ss.setting) for ss in scenes}
    return {
        "preset": preset_name,
        "study": study,
        "config_hash": tables.config_hash(preset),
        "scene_hashes": {ss.scene.name: ss.scene.hash for ss in scenes},
        "seeds": sorted({int(s) for s in df["seed"]}),
        "gap_seeding": "realisation r of a scene draws its gaps from numpy "
                       "default_rng([seed, r])",
        "engines": [e for e in ENGINE_ORDER if e in set(df["engine"])],
        "methods": sorted(set(df["method"])),
        "dt_s": sorted({float(x) for x in df["dt_s"]}),
        "rows": int(len(df)),
        "eq54_bound": eq54,
        **walled,
        **settings,
    }


def gather(preset_name: str, preset: dict, study: str, batch_csvs, timing_csvs,
           out_table, out_summary, out_provenance, out_timing, out_parquet) -> pd.DataFrame:
    """Concatenate a study's batch tables into its table (``out_table``, CSV, and
    ``out_parquet``, its typed Parquet copy), summary, provenance and timing."""
    scenes = study_scenes(preset, study)
    parts = [tables.read_csv(p) for p in batch_csvs]
    df = pd.concat(parts, ignore_index=True) if parts else \
        tables.study_table([], scenes[0].scene.n)
    df = _order(df, scenes)
    expected = sum(ss.members * len(ss.engines) for ss in scenes)
    if len(df) != expected:
        raise GranchainError(f"study '{study}' has {len(df)} rows, the configuration "
                             f"{expected}; delete its work folder and re-run")
    df = df[tables.columns(scenes[0].scene.n,
                           walled=any(ss.scene.wall is not None for ss in scenes),
                           settings=tables.setting_columns(scenes[0].meta))]
    timing = pd.concat([tables.read_csv(p) for p in timing_csvs], ignore_index=True) \
        if timing_csvs else tables.timing_table([])
    tables.write_csv(timing, out_timing)
    tables.write_csv(tables.summary_table(df), out_summary)
    tables.write_provenance(out_provenance, lammps="lammps" in set(df["engine"]),
                            **study_provenance(preset_name, preset, study, scenes, df))
    tables.write_csv(df, out_table)
    # after the CSV: tables.read_table takes the Parquet copy when it is not older
    tables.write_parquet(df, out_parquet)
    return df
