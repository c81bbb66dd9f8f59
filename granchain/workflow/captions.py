"""Sizes of a preset's studies for the report's captions (workflow/report/*.rst).

The rules pass them as params: ``describe`` to the table captions, ``caption_sizes`` to
the figure captions; both read a :class:`~granchain.workflow.presetplan.Plan`.
"""
from __future__ import annotations

import math

from ..errors import GranchainError
from ..scenekeys import DEFAULTS
from .config import FIELD_STUDIES, OPTIONAL_STUDIES, QUESTION_STUDIES
from .presetplan import Plan
from .studies import ENGINE_ORDER

FIGURES = {"packed_sweep": "chapter Fig. 5.1b, 5.1c", "packed_trace": "chapter Fig. 5.1a",
           "gap_profile": "chapter Fig. 5.3b", "gap_sweep": "chapter Fig. 5.3c",
           "extra_length": "chapter Fig. 5.4b", "lammps_check": "LAMMPS cross-validation",
           "precompression": "beyond the chapter: a precompressed chain",
           "wall": "beyond the chapter: the chain on a wall",
           "radius_spread": "beyond the chapter: sphere-size tolerance against Fig. 5.3b",
           "dissipation": "beyond the chapter: contact dissipation against Fig. 5.2",
           "plasticity": "beyond the chapter: yielding contacts against Fig. 5.2",
           "adhesion": "beyond the chapter: adhesive contacts against Fig. 5.2",
           "capture": "beyond the chapter: two adhesive spheres' capture velocity"}
# The probes the figures label and measure: the chapter's (the scene default).
PROBES = tuple(DEFAULTS["probes"])


def describe(plan: Plan, study: str) -> dict:
    """Sizes of a study for the report's table captions."""
    scenes = plan.scenes[study]
    s0 = scenes[0].scene
    speeds = sorted({v for ss in scenes for v in ss.scene.striker_velocities})
    gaps = sorted({ss.gap_mean_nm for ss in scenes})
    extra = sorted({ss.extra_length_um for ss in scenes if not math.isnan(ss.extra_length_um)})
    if extra:
        gap_text = f"gaps from an extra chain length of {', '.join(f'{x:g}' for x in extra)} um"
    elif gaps == [0.0]:
        gap_text = "packed (no gaps)"
    else:
        dist = s0.gap_distribution if s0.gap_distribution != "none" else \
            plan.preset["base"]["gap_distribution"]
        gap_text = f"{dist} gaps of mean {', '.join(f'{g:g}' for g in gaps)} nm"
    engines = [e for e in ENGINE_ORDER if any(e in ss.engines for ss in scenes)]
    if study in FIELD_STUDIES:
        gap_text = "packed, on " + ", ".join(dict.fromkeys(
            f"a {ss.scene.wall.name} wall" + (f" under F0 = {ss.scene.precompression:g} N"
                                              if ss.scene.precompression else "")
            for ss in scenes))
    elif study in QUESTION_STUDIES:
        gap_text = _question_text(scenes, plan.preset["base"]["gap_distribution"])
    return {"preset": plan.name, "figure": FIGURES[study], "scenes": len(scenes),
            "materials": ", ".join(dict.fromkeys(ss.material for ss in scenes)),
            "v_striker": ", ".join(f"{v:g}" for v in speeds),
            "gaps": gap_text if study != "lammps_check" else ", ".join(f"{g:g}" for g in gaps),
            "chains": ", ".join(dict.fromkeys(ss.chain for ss in plan.chains)) or "none",
            "members": sum(ss.members * len(ss.engines) for ss in scenes),
            "jobs": len(plan.batches[study]), "engines": engines,
            "method": ", ".join(dict.fromkeys(ss.scene.method for ss in scenes)),
            "dt_s": f"{s0.dt:g}", "seed": s0.gap_seed, "probes": list(s0.probes[:2])}


def _question_text(scenes, dist: str) -> str:
    """What a question study's scenes are, for the table caption: the radius spreads (or
    the coefficients of restitution) and the gaps of each material."""
    parts = []
    for mat in dict.fromkeys(ss.material for ss in scenes):
        mine = [ss for ss in scenes if ss.material == mat]
        gaps = list(dict.fromkeys(ss.gap_mean_nm for ss in mine))
        gtxt = ", ".join("packed" if g == 0 else f"{dist} gaps of mean {g:g} nm" for g in gaps)
        st = [dict(ss.setting) for ss in mine]
        if "radius_sd_m" in st[0]:
            sds = [x["radius_sd_m"] for x in st if x["radius_sd_m"] > 0]
            dists = ", ".join(dict.fromkeys(x["radius_spread_distribution"] for x in st
                                            if x["radius_sd_m"] > 0))
            parts.append(f"{mat}: {gtxt}; packed with {dists} radius spreads of sd "
                         + ", ".join(f"{x * 1e6:g}" for x in sds) + " um")
        elif "surface_energy_J_m2" in st[0]:
            gs = ", ".join(f"{g:g}" for g in dict.fromkeys(
                x["surface_energy_J_m2"] for x in st if x["surface_energy_J_m2"] > 0))
            grooved = any(x["groove_cohesion"] for x in st)
            model = next(x["cohesion_model"] for x in st if x["cohesion_model"] != "none")
            if all(x["cohesion_model"] != "none" for x in st):
                parts.append(f"{mat}: two spheres with {model} contacts at gamma = {gs} J/m^2")
            else:
                parts.append(f"{mat}: {gtxt}, each without adhesion and with {model} contacts "
                             f"at gamma = {gs} J/m^2" + (", with and without the groove's "
                                                         "flats adhering" if grooved else ""))
        elif "yield_pressure_Pa" in st[0]:
            pys = ", ".join(f"{p / 1e6:.4g}" for p in dict.fromkeys(x["yield_pressure_Pa"]
                                                                    for x in st)
                            if p != float("inf"))
            parts.append(f"{mat}: {gtxt}, each elastic and with Thornton's contacts at p_y = "
                         f"{pys} MPa")
        else:
            es = ", ".join(f"{e:g}" for e in dict.fromkeys(x["restitution_e"] for x in st))
            parts.append(f"{mat}: {gtxt}, each at e = {es} ({st[0]['damping_model']})")
    return "; ".join(parts)


def _method(plan: Plan, study: str) -> str:
    """The integrator a figure caption names: the preset's method, or velocity Verlet in
    LAMMPS for a study on the LAMMPS engine."""
    if any("lammps" in ss.engines for ss in plan.scenes[study]) and study != "lammps_check":
        return "verlet (LAMMPS)"
    if study in OPTIONAL_STUDIES:
        return str(plan.preset["studies"][study].get("method", plan.preset["base"]["method"]))
    return str(plan.preset["base"]["method"])


def caption_sizes(plan: Plan, study: str) -> dict:
    """What a figure caption says about a study's sizes, as plain strings. The figures
    measure the chapter's probes, so a preset with other ``base.probes`` is refused."""
    spec = plan.preset["studies"][study]
    base = plan.preset["base"]
    if list(base.get("probes", PROBES)) != list(PROBES):
        raise GranchainError(f"base.probes {base['probes']}: the figures label and measure "
                             f"the chapter's probes {PROBES[0]} and {PROBES[1]}; remove "
                             "base.probes from the preset")
    out = {"preset": plan.name, "n": str(plan.scenes[study][0].scene.n),
           "radius_um": f"{base['radius'] * 1e6:g}",
           "method": _method(plan, study), "dt_s": f"{base['dt']:g}",
           "materials": ", ".join(sorted(set(plan.materials(study))))}
    if study in OPTIONAL_STUDIES:
        s0 = plan.scenes[study][0].scene
        out["probes"] = f"{s0.probes[0]} and {s0.probes[1]}"
        out["tolerance"] = f"{s0.tolerance:g}" if s0.tolerance else ""
    if study in FIELD_STUDIES:
        out["wall"] = spec["wall"]
    if study in QUESTION_STUDIES:
        out["effects"] = ", ".join(sorted(plan.scenes[study][-1].scene.effects))
        out["gaps"] = _question_text(plan.scenes[study],
                                     plan.preset["base"]["gap_distribution"])
        if study == "radius_spread":
            out["distribution"] = spec.get("distribution", "normal")
            out["seed"] = str(spec.get("seed", base["seed"]))
            out["gap_seed"] = str(base["seed"])
        else:
            out["model"] = spec.get("model", {"dissipation": "coeff_restitution",
                                              "plasticity": "thornton"}.get(study, "jkr"))
            gm = spec.get("gap_mean_nm", [0])
            out["gap_mean_nm"] = "; ".join(
                f"{m}: " + ", ".join(f"{g:g}" for g in (v if isinstance(v, list) else [v]))
                for m, v in gm.items()) if isinstance(gm, dict) else None
    for key in ("v_striker", "gap_mean_nm", "extra_length_um", "realisations", "force_N",
                "sd_um", "e", "yield_pressure_factor", "surface_energy", "t_end_s"):
        if key in spec and out.get(key) is None:
            v = spec[key]
            out[key] = ", ".join(f"{x:g}" for x in v) if isinstance(v, (list, tuple)) \
                else f"{v:g}"
    return out


def vibrometer_sizes(plan: Plan) -> dict:
    """What the vibrometer captions say about the study, as plain strings (empty
    without the study)."""
    if not plan.vibrometer:
        return {}
    spec = plan.preset["studies"]["vibrometer"]
    base = plan.preset["base"]
    gaps = [ss.gap_mean_nm for ss in plan.vibrometer]
    gapped = [g for g in gaps if g > 0]
    return {"preset": plan.name, "n": str(base["n"]), "radius_um": f"{base['radius'] * 1e6:g}",
            "method": str(base["method"]), "dt_s": f"{base['dt']:g}",
            "materials": ", ".join(dict.fromkeys(ss.material for ss in plan.vibrometer)),
            "v_striker": ", ".join(f"{v:g}" for v in spec["v_striker"]),
            "gaps": ("packed" if 0 in gaps else "") + (
                (" and " if 0 in gaps else "") + f"{base.get('gap_distribution', 'uniform')} "
                f"gaps of mean {', '.join(f'{g:g}' for g in gapped)} nm "
                f"({spec['realisations']} realisations)" if gapped else ""),
            "bandwidths_mhz": ", ".join(f"{b / 1e6:g}" for b in sorted(spec["bandwidth_hz"])),
            "filters": ", ".join(spec["filters"]), "order": str(spec["order"]),
            "sampling_rate_mhz": f"{spec['sampling_rate_hz'] / 1e6:g}",
            "chains": str(sum(ss.members for ss in plan.vibrometer))}
