"""One member of a study alone: a chain with only its striker speed and only its gap
realisation, which reproduces its table row bit for bit."""
from __future__ import annotations


from ..errors import GranchainError
from ..simulate import run_scene
from ..tables import SETTING_COLUMNS
from .run import member_rows
from .studies import study_scenes


def rerun_member(preset: dict, study: str, *, material: str, v_striker: float, realisation: int,
                 engine: str | None = None, gap_mean_nm: float | None = None,
                 extra_length_um: float | None = None,
                 precompression_N: float | None = None, **setting) -> dict:
    """Re-run one member of a study alone and return its table row (with the Eq. 5.4
    bound); ``engine``: the study's engine if None (the first of lammps_check's);
    ``precompression_N``: the dead load F0 (N) of a precompression scene; ``setting``:
    the values of a question study's setting columns (``tables.SETTING_COLUMNS``, as its
    rows have them: ``radius_sd_m``, ``restitution_e``, ``yield_pressure_Pa``,
    ``surface_energy_J_m2``, ``groove_cohesion``, ...), which pick its scene."""
    unknown = sorted(set(setting) - set(SETTING_COLUMNS))
    if unknown:
        raise GranchainError(f"rerun_member: unknown setting {', '.join(unknown)}; give "
                             f"setting columns of the study's table: {', '.join(SETTING_COLUMNS)}")

    def matches(ss) -> bool:
        have = dict(ss.setting)
        return all(value is None or (key in have and have[key] == value)
                   for key, value in setting.items())
    cands = [ss for ss in study_scenes(preset, study) if ss.material == material
             and v_striker in ss.scene.striker_velocities
             and (gap_mean_nm is None or ss.gap_mean_nm == gap_mean_nm)
             and (extra_length_um is None or ss.extra_length_um == extra_length_um)
             and (precompression_N is None or ss.scene.precompression == precompression_N)
             and matches(ss)]
    if len(cands) != 1:
        cols = sorted({k for ss in study_scenes(preset, study) for k, _ in ss.setting})
        raise GranchainError(f"{len(cands)} scenes of study '{study}' match; give its "
                             "material, v_striker and gap_mean_nm, extra_length_um, "
                             "precompression_N" + (f" or its setting ({', '.join(cols)})"
                                                   if cols else ""))
    ss = cands[0]
    alone = ss.scene.derive(**{"striker.velocity": float(v_striker)})
    engine = engine or ss.engines[0]
    if engine not in ss.engines:
        raise GranchainError(f"study '{study}' runs on {', '.join(ss.engines)}, not '{engine}'")
    run, = run_scene(alone, engine=engine, realisations=[int(realisation)])
    return member_rows(ss, [run]).iloc[0].to_dict()
