"""LAMMPS against the reference engine on every lammps_check scene (granchain.compare):
tables/lammps_vs_reference.csv and its provenance."""
from __future__ import annotations

import pandas as pd

from .. import tables
from .run import local_mpi
from .studies import check_chain_scenes, study_scenes

# Members per scene whose whole trajectories are compared (the observables are compared
# for every member; the reference engine then holds only these records)
TRACED = 2

# tables/lammps_vs_reference.csv: the scene's columns, then granchain.compare's rows
# (ROW_COLUMNS, v_striker in m/s)
TABLE_COLUMNS = ("study", "chain", "material", "gap_mean_nm", "scene_hash", "member",
                 "realisation", "v_striker_m_s", "quantity", "reference", "lammps", "diff",
                 "measure", "tolerance", "ok", "why")

COMPARISON_META = ("scene_hash", "compared_scene_hash", "chains", "traced_chains", "dt",
                   "sample_dt", "nprocs",
                   "lammps_version", "balance", "tolerances")


def engine_comparison(preset: dict, threads: int | None = None) -> tuple[pd.DataFrame, list]:
    """granchain.compare.compare on every lammps_check scene, then on its field chains
    (``chains``: a dimer, a chain on a wall, a preloaded chain...): per member and
    quantity both engines' values, the difference, its tolerance, ok and why (a walled
    chain adds the wall's rows; the first ``TRACED`` members of each scene add the row of
    their whole trajectories, every particle's v(t) at every sample), in the columns
    ``TABLE_COLUMNS``; column ``chain`` names the field chain ("chapter" for
    lammps_check's own scenes); plus each scene's meta (wall times and temporary paths
    left out, so the table is deterministic)."""
    from .. import compare as cmp
    local_mpi(max(1, int(threads or 1)))
    frames, metas = [], []
    for ss in study_scenes(preset, "lammps_check") + check_chain_scenes(preset):
        c = cmp.compare(ss.scene, nprocs=max(1, int(threads or 1)), traces=TRACED)
        df = c.rows.copy()
        df.insert(0, "study", "lammps_check")
        df.insert(1, "chain", ss.chain or "chapter")
        df.insert(2, "material", ss.material)
        df.insert(3, "gap_mean_nm", ss.gap_mean_nm)
        df.insert(4, "scene_hash", ss.scene.hash)
        df = df.rename(columns={"v_striker": "v_striker_m_s"})
        frames.append(df)
        metas.append({k: c.meta.get(k) for k in COMPARISON_META} | {
            "scene": ss.scene.name, "chain": ss.chain or "chapter", "ok": c.ok})
    return pd.concat(frames, ignore_index=True)[list(TABLE_COLUMNS)], metas


def write_engine_comparison(preset_name: str, preset: dict, out_csv, out_provenance,
                            threads: int | None = None) -> pd.DataFrame:
    df, metas = engine_comparison(preset, threads)
    tables.write_provenance(out_provenance, lammps=True, preset=preset_name,
                            study="lammps_check", config_hash=tables.config_hash(preset),
                            comparisons=metas, all_ok=all(m["ok"] for m in metas))
    tables.write_csv(df, out_csv)
    return df
