"""Study expansion: a preset's study -> its *study scenes*, in table order.

A study expands into one :class:`~granchain.scene.Scene` per material and gap setting,
built with :func:`granchain.scene.scene_from_dict`, so a bad value gets the scene's own
one-line message. A scene's *members* are (striker speed x gap realisation), as in
:func:`granchain.simulate.members`; realisation r of a scene draws its gaps from
``rng([seed, r])`` (:func:`granchain.gaps.realise`), so any member re-runs alone and
reproduces bit for bit.

Studies (chapter figure in brackets):
- packed_sweep  [5.1b, 5.1c] packed chain, striker-speed sweep, per material
- packed_trace  [5.1a] packed chain at one speed, per material; also saves v(t)
- gap_profile   [5.3b] random gaps of one mean, one speed, R realisations
- gap_sweep     [5.3c] mean gaps x striker speeds x R realisations, per material
- extra_length  [5.4b] chains longer than packed by L_extra (gaps from_length)
- lammps_check  both engines on the same members (LAMMPS cross-validation)
- vibrometer    [5.2a] the chapter's instrument: true against recorded v_max,1, v_max,2
                and dt over bandwidths and filters (optional; its own table, not an
                ensemble study: ``vibrometer_scenes``, ``vibrometer_settings``)

The field's chains (optional studies, ``FIELD_STUDIES``; beyond the chapter):
- precompression  a packed chain on an end wall under dead loads F0 (``force_N``), every
                  striker speed: v_g against c0 and Nesterenko's precompressed solitary wave
- wall            the chapter's chain ending on a wall: the wall's force peak against v_s

The chapter's questions (optional studies, ``QUESTION_STUDIES``; beyond Eq. 5.1):
- radius_spread   sphere-size tolerance: the packed chain with each member's radii drawn
                  about the nominal ones (``chain.radius_spread``, one scene per sd), beside
                  the packed chain and the same chain with random gaps (``gap_mean_nm``)
- dissipation     contact damping (effect ``contact_damping``, ``damping: {model, e}``): one
                  scene per coefficient of restitution e, packed and with the mean gaps
                  each material is given
- plasticity      yielding contacts (effect ``plastic_contact``, Thornton's law): the elastic
                  chain and one scene per limiting pressure p_y (factors of the material's
                  library value), every striker speed, packed and with the mean gaps each
                  material is given
- adhesion        adhesive contacts (effect ``adhesion``, LAMMPS's jkr or dmt): the chain
                  without adhesion and one scene per surface energy gamma, with and
                  without the groove's flats adhering (``adhesion.groove``), at the lowest
                  striker speeds
- capture         two adhesive spheres (``chain.n: 2``) at each surface energy over the
                  striker speeds: how each collision ends and its restitution, so the
                  capture velocity against gamma

``lammps_check`` may also name field chains (``chains``: a dimer, a chain on a wall, a
preloaded chain...), which the LAMMPS-vs-reference comparison runs beside its own scenes
(:func:`check_chain_scenes`; they are not part of its batch table).

Every other study runs on one engine (``engine`` key, :func:`.config.study_engine`).
LAMMPS integrates with velocity Verlet, so the scenes of a LAMMPS study say so: their
integrator method is verlet (at the study's dt), and their hashes name what ran.
"""
from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field

from .. import analytic
from ..errors import GranchainError
from ..costmodel import fixed_step
from ..runplan import RunPlan, plan_run
from ..scene import Scene, apply_overrides, scene_from_dict
from ..scenekeys import RANDOM_GAPS, TOLERANCE_METHODS
from .config import FIELD_STUDIES, OPTIONAL_STUDIES, QUESTION_STUDIES, ConfigError, \
    study_engine

STUDIES = ("packed_sweep", "packed_trace", "gap_profile", "gap_sweep", "extra_length",
           "lammps_check")
VIBROMETER = "vibrometer"
ENGINE_ORDER = ("reference", "lammps")


@dataclass(frozen=True)
class StudyScene:
    """One scene of a study: a material and a gap setting, with its striker speeds and
    realisations; ``raw`` is the scene mapping it was built from."""
    study: str
    index: int
    material: str
    gap_mean_nm: float          # nominal mean gap (0: packed)
    extra_length_um: float      # NaN unless the gaps come from an extra chain length
    engines: tuple[str, ...]
    scene: Scene
    raw: dict
    chain: str = ""             # lammps_check: the name of a field chain ("": its own)
    # a question study's setting columns and their values (tables.SETTING_COLUMNS): the
    # radius spread, the contact damping
    setting: tuple[tuple[str, object], ...] = ()
    # the scene's run plan (granchain.runplan), built once with the scene
    run_plan: RunPlan | None = field(default=None, compare=False, repr=False)

    @property
    def plan(self) -> RunPlan:
        """The run plan of the scene: auto's choice, steps, wall time per member."""
        return self.run_plan if self.run_plan is not None else plan_run(self.scene)

    @property
    def eq54(self) -> bool:
        """Does the table row get the Eq. 5.4 bound (a packed reference run)? Not for the
        field's studies, whose chains are packed (a wall, a preload: the bound is about
        gaps), nor for the chapter's questions (a radius spread, contact damping: the bound
        is about elastic chains of equal spheres), nor for lammps_check's field chains."""
        return self.study not in OPTIONAL_STUDIES and not self.chain

    @property
    def packed_engine(self) -> str:
        """The engine of the packed chain behind the rows' Eq. 5.4 bound: the study's
        engine, so a row and its bound come from one engine; lammps_check, which runs
        both engines on the same members, gives both engines' rows the reference
        engine's packed chain (one shared input, so the bound column compares equal)."""
        return self.engines[0] if len(self.engines) == 1 else "reference"

    @property
    def meta(self) -> dict:
        return {"study": self.study, "material": self.material,
                "gap_distribution": self.scene.gap_distribution,
                "gap_mean_nm": self.gap_mean_nm, "extra_length_um": self.extra_length_um,
                "seed": self.seed, "scene_hash": self.scene.hash, **dict(self.setting)}

    @property
    def seed(self) -> int:
        """The seed of the row's random draws: the gaps' (``gaps.seed``), or a packed
        chain's radius spread's (``chain.radius_spread.seed``)."""
        sp = self.scene.radius_spread
        if sp is not None and self.scene.gap_distribution == "none":
            return int(sp.seed)
        return int(self.scene.gap_seed)

    @property
    def members(self) -> int:
        return len(self.scene.striker_velocities) * self.scene.realisations


def _as_list(x):
    return list(x) if isinstance(x, (list, tuple)) else [x]


def _fmt_num(x: float) -> str:
    return f"{x:g}".replace("+", "")


def _study_materials(preset: dict, spec: dict) -> list[str]:
    if "material" in spec:
        return [spec["material"]]
    return list(spec.get("materials") or preset["materials"])


def _raw_scene(preset: dict, spec: dict, name: str, material: str, velocities, gaps: dict,
               realisations: int, engine: str = "reference") -> dict:
    base = preset["base"]
    # LAMMPS integrates velocity Verlet at the study's dt, whatever the preset's method
    method = "verlet" if engine == "lammps" else spec.get("method", base["method"])
    raw = {
        "name": name,
        "material": material,
        "chain": {"n": base["n"], "radius": base["radius"]},
        "striker": {"velocity": list(velocities) if len(velocities) > 1 else velocities[0]},
        # the seed only where gaps are drawn at random (elsewhere it has no effect)
        "gaps": dict(gaps, seed=base["seed"]) if gaps.get("distribution") in RANDOM_GAPS
        else dict(gaps),
        "effects": list(base["effects"]),
        "integrator": {"method": method, "dt": spec.get("dt", base["dt"])},
        "ensemble": {"realisations": int(realisations)},
    }
    if raw["integrator"]["method"] == "auto" and "dt" not in spec:
        del raw["integrator"]["dt"]          # auto chooses its own step
    tol = spec.get("tolerance", base.get("tolerance"))
    if tol is not None and method in (*TOLERANCE_METHODS, "auto"):
        raw["integrator"]["tolerance"] = tol
    if "probes" in base:
        raw["probes"] = list(base["probes"])
    return apply_overrides(raw, list(base.get("overrides", [])) + list(spec.get("overrides", [])))


def _build(raw: dict, where: str) -> RunPlan:
    """The run plan of a study scene: its scene (``.scene``) has method auto resolved (its
    hash covers the setting it runs)."""
    try:
        return plan_run(scene_from_dict(raw))
    except GranchainError as exc:
        raise ConfigError(f"invalid configuration at '{where}' (scene {raw['name']}): {exc}") \
            from None


def _scene_and_raw(raw: dict, where: str) -> tuple:
    """(scene, raw) of a StudyScene, its run plan as ``run_plan`` (:func:`_build`)."""
    p = _build(raw, where)
    return p.scene, raw, "", (), p


def _check_scene(raw: dict, spec: dict, where: str) -> RunPlan:
    """A lammps_check scene: with ``steps_per_contact`` N its step is the Hertz contact
    time at its striker speed over N, on its sample grid (``costmodel.fixed_step``, as the
    accuracy study sets Verlet's step), so a slower striker takes a larger step; else the
    study's (or base) dt. Both engines run that step (``granchain.compare``). Its run
    plan, as :func:`_build`'s."""
    n = spec.get("steps_per_contact")
    if n is None:
        return _build(raw, where)
    if "dt" in spec:
        raise ConfigError("invalid configuration at 'studies.lammps_check': both dt and "
                          "steps_per_contact are given; give one of them")
    raw["integrator"]["dt"] = fixed_step(_build(raw, where).scene, int(n))
    return _build(raw, where)


def preset_studies(preset: dict) -> list[str]:
    """The ensemble studies of a preset, in order: every one of ``STUDIES``, then the
    optional ones (``OPTIONAL_STUDIES``: the field's studies, the chapter's questions) the
    preset has."""
    return list(STUDIES) + [s for s in OPTIONAL_STUDIES
                            if (preset.get("studies") or {}).get(s)]


def study_scenes(preset: dict, study: str) -> list[StudyScene]:
    """The scenes of one study of a preset, in table order."""
    if study in FIELD_STUDIES:
        return field_scenes(preset, study)
    if study in QUESTION_STUDIES:
        return question_scenes(preset, study)
    if study not in STUDIES:
        raise ConfigError(f"unknown study '{study}'; use one of "
                          f"{', '.join(STUDIES + OPTIONAL_STUDIES)}")
    spec = preset["studies"][study]
    where = f"studies.{study}"
    dist = preset["base"]["gap_distribution"]
    out: list[StudyScene] = []

    def add(material, velocities, gaps, realisations, gap_nm, extra_um, suffix, engines):
        name = f"{study}-{material}" + (f"-{suffix}" if suffix else "")
        raw = _raw_scene(preset, spec, name, material, velocities, gaps, realisations,
                         engines[0] if len(engines) == 1 else "reference")
        p = _check_scene(raw, spec, where) if study == "lammps_check" else _build(raw, where)
        out.append(StudyScene(study, len(out), material, float(gap_nm), float(extra_um),
                              tuple(engines), p.scene, raw, run_plan=p))

    engines = (study_engine(spec),)
    if study == "lammps_check":
        engines = tuple(e for e in ENGINE_ORDER if e in spec["engines"])
    for material in _study_materials(preset, spec):
        v = _as_list(spec["v_striker"])
        if study in ("packed_sweep", "packed_trace"):
            add(material, v, {"distribution": "none"}, 1, 0.0, math.nan, "", engines)
        elif study in ("gap_profile", "gap_sweep", "lammps_check"):
            for g in _as_list(spec["gap_mean_nm"]):
                gaps = {"distribution": "none"} if g == 0 else \
                    {"distribution": dist, "mean": float(g) * 1e-9}
                reals = 1 if g == 0 else spec["realisations"]
                if study != "lammps_check":
                    add(material, v, gaps, reals, g, math.nan, f"gap{_fmt_num(g)}nm", engines)
                    continue
                # One scene per striker speed, each a run of its own on either engine
                # (both sample each chain on its own grid whatever the batching).
                for vi in v:
                    add(material, [vi], gaps, reals, g, math.nan,
                        f"gap{_fmt_num(g)}nm-v{_fmt_num(vi)}", engines)
        elif study == "extra_length":
            n = preset["base"]["n"]
            for L in _as_list(spec["extra_length_um"]):
                gaps = {"distribution": "from_length", "extra_length": float(L) * 1e-6}
                add(material, v, gaps, spec["realisations"], float(L) * 1e3 / (n - 1), L,
                    f"extra{_fmt_num(L)}um", engines)
    return out


def _fmt_force(F0: float) -> str:
    return f"{F0:g}".replace("+", "").replace("-", "m")


def field_scenes(preset: dict, study: str) -> list[StudyScene]:
    """The scenes of a field study (none if the preset lacks it), one per material (and
    per dead load F0 of ``precompression``), every striker speed, packed, ending on the
    study's ``wall``; ``n`` and ``probes`` replace the base chain's when given.

    precompression: ``force_N`` lists the loads (0: the unloaded chain on the wall, the
    Nesterenko limit). wall: the chapter's chain on the wall."""
    spec = (preset.get("studies") or {}).get(study)
    if not spec:
        return []
    where = f"studies.{study}"
    engines = (study_engine(spec),)
    forces = [float(f) for f in _as_list(spec["force_N"])] if study == "precompression" \
        else [0.0]
    out: list[StudyScene] = []
    for material in _study_materials(preset, spec):
        for F0 in forces:
            name = f"{study}-{material}-wall-{spec['wall']}" if study == "wall" else \
                f"{study}-{material}-F{_fmt_force(F0)}N"
            raw = _raw_scene(preset, spec, name, material, _as_list(spec["v_striker"]),
                             {"distribution": "none"}, 1, engines[0])
            if "n" in spec:
                raw["chain"]["n"] = int(spec["n"])
            if "probes" in spec:
                raw["probes"] = list(spec["probes"])
            raw["walls"] = {"end": spec["wall"]}
            if F0 > 0:
                raw["precompression"] = {"force": F0}
            out.append(StudyScene(study, len(out), material, 0.0, math.nan, engines,
                                  *_scene_and_raw(raw, where)))
    return out


def _gaps(preset: dict, g: float) -> dict:
    """The gaps section of a mean gap g in nm (0: packed), the preset's gap law."""
    return {"distribution": "none"} if g == 0 else \
        {"distribution": preset["base"]["gap_distribution"], "mean": float(g) * 1e-9}


def _material_gaps(spec: dict, materials: list[str], where: str) -> dict[str, list[float]]:
    """Each material's mean gaps (nm; 0: packed) of the dissipation study: ``gap_mean_nm`` a
    list for every material, or a mapping material -> list (every study material needs
    one, and none other is allowed)."""
    gm = spec["gap_mean_nm"]
    if not isinstance(gm, dict):
        return {m: [float(g) for g in _as_list(gm)] for m in materials}
    missing = [m for m in materials if m not in gm]
    extra = [m for m in gm if m not in materials]
    if missing or extra:
        what = (f"no mean gaps for material '{missing[0]}'" if missing else
                f"material '{extra[0]}' is not one of the study's ({', '.join(materials)})")
        raise ConfigError(f"invalid configuration at '{where}.gap_mean_nm': {what}; give one "
                          "list of mean gaps (nm, 0: packed) per material of the study")
    return {m: [float(g) for g in _as_list(gm[m])] for m in materials}


def question_scenes(preset: dict, study: str) -> list[StudyScene]:
    """The scenes of a question study (none if the preset lacks it), per material, at the
    study's striker speeds (one for radius_spread and dissipation); each row carries the
    study's setting columns.

    radius_spread: the packed chain (one chain, no spread), then one packed scene per sd in
    ``sd_um`` whose members draw their radii about the nominal ones
    (``chain.radius_spread``: the study's ``distribution``, seed ``seed`` or the base seed;
    every sd draws the same normalised deviations, scaled), then the same chain with random
    gaps of each mean in ``gap_mean_nm`` and no spread; ``realisations`` each.
    dissipation: per mean gap of the material (0: packed, one chain; else
    ``realisations``), one scene per coefficient of restitution in ``e``: the base effects
    plus ``contact_damping`` with ``damping: {model, e}``. plasticity:
    :func:`_plasticity_scenes`; adhesion: :func:`_adhesion_scenes`; capture:
    :func:`_capture_scenes`."""
    spec = (preset.get("studies") or {}).get(study)
    if not spec:
        return []
    where = f"studies.{study}"
    engine = study_engine(spec)
    v = _as_list(spec["v_striker"])
    reals = int(spec["realisations"])
    materials = _study_materials(preset, spec)
    out: list[StudyScene] = []

    def add(material, suffix, gaps, realisations, gap_nm, setting, edit):
        raw = _raw_scene(preset, spec, f"{study}-{material}-{suffix}", material, v,
                         gaps, realisations, engine)
        edit(raw)
        p = _build(raw, where)
        out.append(StudyScene(study, len(out), material, float(gap_nm), math.nan, (engine,),
                              p.scene, raw, setting=tuple(setting), run_plan=p))

    if study == "radius_spread":
        dist = spec.get("distribution", "normal")
        seed = int(spec.get("seed", preset["base"]["seed"]))
        none = (("radius_spread_distribution", "none"), ("radius_sd_m", 0.0))
        for material in materials:
            add(material, "packed", {"distribution": "none"}, 1, 0.0, none, lambda raw: None)
            for sd in _as_list(spec["sd_um"]):
                sd_m = float(sd) * 1e-6

                def spread(raw, sd_m=sd_m):
                    raw["chain"]["radius_spread"] = {"distribution": dist, "sd": sd_m,
                                                     "seed": seed}
                add(material, f"sd{_fmt_num(sd)}um", {"distribution": "none"}, reals, 0.0,
                    (("radius_spread_distribution", dist), ("radius_sd_m", sd_m)), spread)
            for g in _as_list(spec.get("gap_mean_nm", [])):
                add(material, f"gap{_fmt_num(g)}nm", _gaps(preset, g), reals, g, none,
                    lambda raw: None)
        return out

    if study == "plasticity":
        _plasticity_scenes(preset, spec, materials, add, where)
        return out
    if study == "adhesion":
        _adhesion_scenes(preset, spec, materials, add, where)
        return out
    if study == "capture":
        _capture_scenes(spec, materials, add)
        return out

    model = spec.get("model", "coeff_restitution")

    def damped(e):
        def edit(raw):
            if "contact_damping" not in raw["effects"]:
                raw["effects"].append("contact_damping")
            raw["damping"] = {"model": model, "e": float(e)}
        return edit

    for material, gaps in _material_gaps(spec, materials, where).items():
        for g in gaps:
            for e in _as_list(spec["e"]):
                add(material, f"gap{_fmt_num(g)}nm-e{_fmt_num(e)}", _gaps(preset, g),
                    1 if g == 0 else reals, g,
                    (("damping_model", model), ("restitution_e", float(e))), damped(e))
    return out


def _plasticity_scenes(preset: dict, spec: dict, materials: list[str], add, where: str):
    """plasticity: per mean gap of the material (0: packed, one chain; else
    ``realisations``), the elastic chain (p_y infinite), then one scene per factor in
    ``yield_pressure_factor``: the effect ``plastic_contact`` with p_y that factor times the
    material's library value (``materials.yaml``). The base effects that Thornton's law does
    not act with yet (``plastic_contact.NOT_WITH``: the contact and rolling friction) are left
    out of every scene of the study, the elastic one included."""
    from ..effects.plastic_contact import MODELS, NOT_WITH
    from ..materials import library
    model = MODELS[0]
    reals = int(spec["realisations"])
    elastic = (("plasticity_model", "none"), ("yield_pressure_Pa", math.inf))

    def edit(py):
        def apply(raw):
            raw["effects"] = [e for e in raw["effects"] if e not in NOT_WITH]
            if py is not None:
                raw["effects"].append("plastic_contact")
                raw["plasticity"] = {"model": model, "yield_pressure": float(py)}
        return apply

    known = library()
    for material, gaps in _material_gaps(spec, materials, where).items():
        mat = known.get(material)
        if mat is None or mat.yield_pressure is None:
            have = ", ".join(k for k, m in known.items() if m.yield_pressure is not None)
            raise ConfigError(f"invalid configuration at '{where}': material '{material}' has "
                              "no yield_pressure in the material library; study materials "
                              f"that have one ({have})")
        for g in gaps:
            r = 1 if g == 0 else reals
            add(material, f"gap{_fmt_num(g)}nm-elastic", _gaps(preset, g), r, g,
                      elastic, edit(None))
            for f in _as_list(spec["yield_pressure_factor"]):
                py = float(f) * mat.yield_pressure
                add(material, f"gap{_fmt_num(g)}nm-py{_fmt_num(f)}", _gaps(preset, g),
                          r, g, (("plasticity_model", model), ("yield_pressure_Pa", py)),
                          edit(py))


def _adhesion_scenes(preset: dict, spec: dict, materials: list[str], add, where: str):
    """adhesion: per mean gap of the material (0: packed, one chain; else
    ``realisations``), the chain without adhesion, then one scene per surface energy gamma
    in ``surface_energy`` (J/m^2) and groove setting in ``groove`` (the groove's flats
    adhere too: ``adhesion.groove``): the effect ``adhesion`` with ``adhesion: {model,
    surface_energy, groove}``. The base effects the model does not act with
    (``adhesion.not_with``: none today) are left out of every scene of the study, the one
    without adhesion included."""
    from ..effects.adhesion import not_with
    model = spec.get("model", "jkr")
    drop = not_with(model)
    reals = int(spec["realisations"])
    none = (("cohesion_model", "none"), ("surface_energy_J_m2", 0.0), ("groove_cohesion", False))

    def edit(gamma, groove):
        def apply(raw):
            raw["effects"] = [e for e in raw["effects"] if e not in drop]
            if gamma is not None:
                raw["effects"].append("adhesion")
                raw["adhesion"] = {"model": model, "surface_energy": float(gamma),
                                   "groove": bool(groove)}
        return apply

    for material, gaps in _material_gaps(spec, materials, where).items():
        for g in gaps:
            r = 1 if g == 0 else reals
            add(material, f"gap{_fmt_num(g)}nm-none", _gaps(preset, g), r, g, none,
                edit(None, False))
            for groove in _as_list(spec["groove"]):
                for gamma in _as_list(spec["surface_energy"]):
                    tag = f"gap{_fmt_num(g)}nm-{model}{_fmt_num(gamma)}" + \
                        ("-groove" if groove else "")
                    add(material, tag, _gaps(preset, g), r, g,
                        (("cohesion_model", model), ("surface_energy_J_m2", float(gamma)),
                         ("groove_cohesion", bool(groove))), edit(gamma, groove))


def _capture_scenes(spec: dict, materials: list[str], add):
    """capture: per material and surface energy gamma in ``surface_energy``, one two-sphere
    scene (``chain.n: 2``, the restitution experiment) at every striker speed: the contact
    law alone (effects hertz and adhesion, ``model``), no groove and no air, run to the
    fixed ``t_end_s`` (a pair held closed in tension is not an end the run can wait for)."""
    model = spec.get("model", "jkr")
    for material in materials:
        for gamma in _as_list(spec["surface_energy"]):
            def edit(raw, gamma=gamma):
                raw["chain"] = {"n": 2, "radius": raw["chain"]["radius"]}
                raw["effects"] = ["hertz", "adhesion"]
                raw["adhesion"] = {"model": model, "surface_energy": float(gamma)}
                raw["t_end"] = float(spec["t_end_s"])
                raw.pop("probes", None)
            add(material, f"{model}{_fmt_num(gamma)}", {"distribution": "none"}, 1, 0.0,
                (("cohesion_model", model), ("surface_energy_J_m2", float(gamma)),
                 ("groove_cohesion", False)), edit)


def _pattern(values, n: int, where: str) -> list:
    """A list repeated along a chain of n spheres from the striker (a dimer's two radii
    -> n alternating radii)."""
    values = _as_list(values)
    if len(values) > n:
        raise ConfigError(f"invalid configuration at '{where}': {len(values)} values for a "
                          f"chain of {n} spheres; give at most {n} (they repeat along the chain)")
    return [values[i % len(values)] for i in range(n)]


def check_chain_scenes(preset: dict) -> list[StudyScene]:
    """lammps_check's field chains (its ``chains`` list; none without it): for each chain,
    material and mean gap (the chain's ``gap_mean_nm``, default packed), one scene per
    striker speed, as lammps_check's own scenes, with the chain's radii and materials
    (repeated along the chain from the striker), striker, end wall and dead load."""
    spec = preset["studies"]["lammps_check"]
    chains = spec.get("chains") or []
    where = "studies.lammps_check.chains"
    names = [c["name"] for c in chains]
    for name in names:
        if names.count(name) > 1:
            raise ConfigError(f"invalid configuration at '{where}': chain name '{name}' is "
                              "given twice; give each chain its own name")
    engines = tuple(e for e in ENGINE_ORDER if e in spec["engines"])
    dist = preset["base"]["gap_distribution"]
    n = int(preset["base"]["n"])
    out: list[StudyScene] = []
    for k, ch in enumerate(chains):
        at = f"{where}.{k}"
        # a chain with materials of its own is the same chain for every study material
        # (the scene takes no `material` beside chain.materials): built once, for the first
        materials = _study_materials(preset, spec)[:1 if "materials" in ch else None]
        for material in materials:
            for g in _as_list(ch.get("gap_mean_nm", [0])):
                gaps = {"distribution": "none"} if g == 0 else \
                    {"distribution": dist, "mean": float(g) * 1e-9}
                reals = 1 if g == 0 else spec["realisations"]
                for vi in _as_list(spec["v_striker"]):
                    name = (f"lammps_check-{material}-{ch['name']}-gap{_fmt_num(g)}nm-"
                            f"v{_fmt_num(vi)}")
                    raw = _raw_scene(preset, spec, name, material, [vi], gaps, reals)
                    if "radius" in ch:
                        raw["chain"]["radius"] = _pattern(ch["radius"], n, f"{at}.radius")
                    if "materials" in ch:
                        raw["chain"]["materials"] = _pattern(ch["materials"], n,
                                                             f"{at}.materials")
                        del raw["material"]
                    for key in ("material", "radius"):
                        if f"striker_{key}" in ch:
                            raw["striker"][key] = ch[f"striker_{key}"]
                    if "wall" in ch:
                        raw["walls"] = {"end": ch["wall"]}
                    if "precompression_N" in ch:
                        raw["precompression"] = {"force": float(ch["precompression_N"])}
                    raw = apply_overrides(raw, list(ch.get("overrides", [])))
                    p = _check_scene(raw, spec, at)
                    out.append(StudyScene("lammps_check", len(out), material, float(g),
                                          math.nan, engines, p.scene, raw, ch["name"],
                                          run_plan=p))
    return out


def packed_scene(ss: StudyScene) -> Scene:
    """The packed chain of a study scene: same physics, striker speeds, method and dt."""
    raw = copy.deepcopy(ss.raw)
    raw["name"] = f"{ss.study}-{ss.material}-packed"
    raw["gaps"] = {"distribution": "none"}
    raw["ensemble"] = {"realisations": 1}
    return scene_from_dict(raw)


def trace_scene(ss: StudyScene) -> Scene:
    """The packed_trace scene with t_end long enough for the pulse to cross all n spheres
    (1.5x the Nesterenko travel time of n + 1 diameters at 0.64 v_s, the chapter's v_max)."""
    sc = ss.scene
    v = float(sc.striker_velocities[0])
    travel = (sc.n + 1) * 2.0 * sc.radius / float(analytic.nesterenko_speed(sc.material, 0.64 * v))
    raw = copy.deepcopy(ss.raw)
    raw["t_end"] = 1.5 * travel
    return _build(raw, "studies.packed_trace").scene


def vibrometer_scenes(preset: dict) -> list[StudyScene]:
    """The vibrometer study's scenes (none if the preset has no ``vibrometer`` study): one
    per mean gap (0: the packed chain, one realisation; else ``realisations``), every
    striker speed, on the reference engine. Each carries the study's first instrument
    setting as its measurement block (so ``vibrometer.needs_trace`` holds for it); the
    other settings filter the same trajectories (:func:`vibrometer_settings`)."""
    spec = (preset.get("studies") or {}).get(VIBROMETER)
    if not spec:
        return []
    where = f"studies.{VIBROMETER}"
    dist = preset["base"]["gap_distribution"]
    first = vibrometer_blocks(spec)[0]
    out: list[StudyScene] = []
    for material in _study_materials(preset, spec):
        for g in _as_list(spec["gap_mean_nm"]):
            gaps = {"distribution": "none"} if g == 0 else \
                {"distribution": dist, "mean": float(g) * 1e-9}
            reals = 1 if g == 0 else spec["realisations"]
            name = f"{VIBROMETER}-{material}-gap{_fmt_num(g)}nm"
            raw = _raw_scene(preset, spec, name, material, _as_list(spec["v_striker"]), gaps,
                             reals)
            raw["measurement"] = dict(first)
            out.append(StudyScene(VIBROMETER, len(out), material, float(g), math.nan,
                                  ("reference",), *_scene_and_raw(raw, where)))
    return out


def vibrometer_blocks(spec: dict) -> list[dict]:
    """The measurement blocks of the vibrometer study, filter by filter, bandwidth by
    bandwidth (ascending): the study's order and sampling rate, no noise."""
    return [{"bandwidth_hz": float(bw), "filter": f, "order": int(spec["order"]),
             "sampling_rate_hz": float(spec["sampling_rate_hz"])}
            for f in spec["filters"] for bw in sorted(_as_list(spec["bandwidth_hz"]))]


def vibrometer_settings(preset: dict, ss: StudyScene) -> list:
    """The instrument settings (:class:`granchain.scenecheck.Measurement`) the vibrometer study
    applies to the trajectories of a scene, each validated as the scene's measurement
    block (a bandwidth not below half the sampling rate is refused in one line)."""
    spec = preset["studies"][VIBROMETER]
    out = []
    for block in vibrometer_blocks(spec):
        try:
            out.append(ss.scene.derive(measurement=block).measurement)
        except GranchainError as exc:
            raise ConfigError(f"invalid configuration at 'studies.{VIBROMETER}' (scene "
                              f"{ss.scene.name}): {exc}") from None
    return out
