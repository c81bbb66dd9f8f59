"""The scene's checks: each value of a scene mapping checked against its declaration
(``granchain.scenekeys``) and turned into what the :class:`~granchain.scene.Scene` holds
(its materials, spheres, radius spread, effects, probes and vibrometer), the keys refused
as having no effect, and the checks of what the values make of the chain (finite masses,
Hertz constants and collision times, overlaps, the step, the sample interval).

Every problem is a one-line :class:`~granchain.errors.SceneError` naming the key and the
fix. ``granchain.scene`` assembles the Scene from these checks.
"""
from __future__ import annotations

import copy
import difflib
import math
import re
from dataclasses import dataclass

from .errors import SceneError
from .validate import short as _short
from .scenekeys import (ALWAYS, DEFAULTS, FIXED_STEP_METHODS, KEY_BY_PATH, MAX_FILTER_ORDER,
                        MEASUREMENT_DEFAULTS, MIN_STEPS_PER_CONTACT, NAME_RE, NAME_RULE,
                        NORMAL_TRUNCATION, OPTIONAL_KEYS, RADIUS_SPREAD_DEFAULTS, RANDOM_GAPS,
                        REQUIRES, SECTIONED)
from .guards import (MIN_SAMPLES_PER_PULSE, check_overlaps, floor_sig, max_sample_dt,
                     pulse_width)
from .effects import MODULES as EFFECT_MODULES, SPECS as EFFECT_SPECS
from .materials import FIELD_FIX, FIELDS, RIGID, Material, library


@dataclass(frozen=True)
class Measurement:
    """The vibrometer of a scene (``measurement:`` block): -3 dB bandwidth (Hz) of a
    causal low-pass ``filter`` (butterworth or bessel) of ``order``, digitised at
    ``sampling_rate_hz``, with additive white noise of RMS ``noise_rms_m_s`` (m/s) drawn
    from ``seed``."""
    bandwidth_hz: float
    filter: str
    order: int
    sampling_rate_hz: float
    noise_rms_m_s: float
    seed: int


@dataclass(frozen=True)
class RadiusSpread:
    """Each member's radii R_i + e_i, e_i i.i.d. with standard deviation ``sd`` (m):
    ``normal`` truncated at NORMAL_TRUNCATION sd, or ``uniform`` on +-sqrt(3) sd; drawn
    from numpy default_rng([seed, realisation, RADIUS_STREAM]) (``gaps.member_radii``)."""
    distribution: str
    sd: float
    seed: int

    @property
    def half_width(self) -> float:
        """The largest |e_i| a draw can give (m)."""
        return (NORMAL_TRUNCATION if self.distribution == "normal" else math.sqrt(3.0)) * self.sd


def merge(defaults: dict, given: dict, prefix: str = "") -> dict:
    out = copy.deepcopy(defaults)
    for key, value in given.items():
        where = f"{prefix}{key}"
        if key not in defaults:
            close = difflib.get_close_matches(str(key), list(defaults), n=1)
            hint = f"did you mean '{prefix}{close[0]}'?" if close else \
                f"known keys: {', '.join(defaults)}"
            raise SceneError(where, "unknown key", hint)
        if isinstance(defaults[key], dict) and key != "material":
            if value is None:
                continue
            if not isinstance(value, dict):
                raise SceneError(where, f"expected a mapping, got {_short(value)}",
                                 f"write e.g. {key}: {{...}}")
            out[key] = merge(defaults[key], value, where + ".")
        else:
            out[key] = value
    return out


def number(spec: dict, dotted: str, *, allow_none: bool = False, fix: str | None = None):
    """The number at a dotted key of a merged spec, checked against the key's bounds
    (its declaration in ``KEYS``)."""
    return KEY_BY_PATH[dotted].number(_get(spec, dotted), allow_none=allow_none, fix=fix)


def check_name(value, field: str) -> str:
    """A name that may reach deck comments, data-file titles and file names."""
    if isinstance(value, bool) or not isinstance(value, (str, int)):
        raise SceneError(field, f"expected a name, got {_short(value)}", NAME_RULE)
    text = str(value)
    if not NAME_RE.fullmatch(text):
        raise SceneError(field, f"{_short(text)} is not a valid name", NAME_RULE)
    return text


def _get(spec, dotted):
    node = spec
    for p in dotted.split("."):
        node = node[p]
    return node


def material_of(value, where: str = "material", *, wall: bool = False) -> Material:
    """A library material by name or a mapping {E, nu, rho} (a wall: {E, nu}, or 'rigid');
    ``where`` names the key in errors."""
    lib = library()
    keys = ("E", "nu") if wall else ("E", "nu", "rho")
    example = "{E: 200e9, nu: 0.28}" if wall else "{E: 200e9, nu: 0.28, rho: 7800}"
    if isinstance(value, str):
        if wall and value == "rigid":
            return RIGID
        if value not in lib:
            names = list(lib) + (["rigid"] if wall else [])
            close = difflib.get_close_matches(value, names, n=1)
            hint = f"did you mean '{close[0]}'?" if close else f"use one of {', '.join(names)}"
            raise SceneError(where, f"unknown material {_short(value)}",
                             f"{hint} or give {example}")
        return lib[value]
    if isinstance(value, dict):
        extra = set(value) - set(keys) - {"name"}
        if extra:
            key = sorted(map(str, extra))[0]
            if wall and key == "rho":
                raise SceneError(f"{where}.rho", "has no effect: the wall does not move",
                                 f"drop it; a wall takes E and nu, e.g. {example}")
            raise SceneError(f"{where}.{key}", "unknown key",
                             f"a material mapping has {', '.join(keys)} (and optional name)")
        for k in keys:
            if k not in value:
                raise SceneError(f"{where}.{k}", "missing",
                                 "give E (Pa), nu" + ("" if wall else " and rho (kg/m^3)"))
        E, nu = (FIELDS[k].number(value[k], field=f"{where}.{k}", fix=FIELD_FIX[k])
                 for k in ("E", "nu"))
        rho = FIELDS["rho"].number(value["rho"], field=f"{where}.rho",
                                   fix=FIELD_FIX["rho"]) if not wall else 0.0
        name = check_name(value.get("name", "custom"), f"{where}.name")
        return Material(name, E, nu, rho)
    raise SceneError(where, f"expected a name or a mapping, got {_short(value)}",
                     f"write {where.rpartition('.')[2].split('[')[0]}: ss440c or {example}")


def chain_spheres(spec: dict, n: int, material: Material, given: set[str]):
    """(radii, materials) of the n spheres, particle 1 (the striker) first, from
    chain.radius, chain.materials, striker.radius and striker.material. A key another one
    overrides is refused: ``material`` (given) beside a chain.materials list, striker.radius
    beside a chain.radius list, striker.material beside a chain.materials list."""
    rad = spec["chain"]["radius"]
    fix = "give the sphere radius in metres, e.g. 150e-6"
    if isinstance(rad, list):
        if len(rad) != n:
            raise SceneError("chain.radius", f"has {len(rad)} entries but the chain has n = {n} "
                             "spheres", f"give one radius, or a list of exactly n = {n} radii "
                             "(particle 1, the striker, first)")
        radii = [KEY_BY_PATH["chain.radius"].number(r, field=f"chain.radius[{i}]", fix=fix)
                 for i, r in enumerate(rad)]
    else:
        radii = [number(spec, "chain.radius", fix=fix)] * n
    mats = spec["chain"].get("materials")
    if mats is None:
        materials = [material] * n
    else:
        if isinstance(mats, (str, dict)):          # one material: that is `material`
            one = mats if isinstance(mats, str) and NAME_RE.fullmatch(mats) else "..."
            raise SceneError("chain.materials", f"takes a list of n = {n} materials, got one "
                             f"({_short(mats)})", f"for one material for every sphere write "
                             f"material: {one} and drop chain.materials")
        if not isinstance(mats, list):
            raise SceneError("chain.materials", f"expected a list, got {_short(mats)}",
                             f"give a list of n = {n} materials, or drop it")
        if "material" in given:
            raise SceneError("material", "has no effect beside the chain.materials list, "
                             "which gives every sphere's material",
                             "drop material (--set material=null), or drop chain.materials")
        if len(mats) != n:
            raise SceneError("chain.materials", f"has {len(mats)} entries but the chain has "
                             f"n = {n} spheres", f"give exactly n = {n} materials "
                             "(particle 1, the striker, first)")
        materials = [material_of(m, f"chain.materials[{i}]") for i, m in enumerate(mats)]
    if spec["striker"].get("radius") is not None:
        if isinstance(rad, list):
            raise SceneError("striker.radius", "given beside the chain.radius list, whose "
                             "first entry is already the striker's radius",
                             "drop striker.radius, or set the striker's radius as "
                             "chain.radius[0]")
        radii[0] = number(spec, "striker.radius",
                          fix="give the striker's radius in metres, e.g. 189e-6")
    if spec["striker"].get("material") is not None:
        if mats is not None:
            raise SceneError("striker.material", "given beside the chain.materials list, "
                             "whose first entry is already the striker's material",
                             "drop striker.material, or set the striker's material as "
                             "chain.materials[0]")
        materials[0] = material_of(spec["striker"]["material"], "striker.material")
    return tuple(radii), tuple(materials)


def radius_spread_of(value, radii) -> RadiusSpread | None:
    """The validated chain.radius_spread block (None when not given)."""
    if value is None:
        return None
    where = "chain.radius_spread"
    if not isinstance(value, dict):
        raise SceneError(where, f"expected a mapping, got {_short(value)}",
                         "write radius_spread: {distribution: normal, sd: 0.3e-6}")
    extra = set(value) - set(RADIUS_SPREAD_DEFAULTS)
    if extra:
        key = sorted(map(str, extra))[0]
        close = difflib.get_close_matches(key, list(RADIUS_SPREAD_DEFAULTS), n=1)
        raise SceneError(f"{where}.{key}", "unknown key",
                         f"did you mean '{where}.{close[0]}'?" if close else
                         "a radius spread has distribution, sd and seed")
    dist = KEY_BY_PATH[f"{where}.distribution"].choice(
        value.get("distribution", RADIUS_SPREAD_DEFAULTS["distribution"]), "distribution")
    if "sd" not in value:
        raise SceneError(f"{where}.sd", "missing", "give the standard deviation of the radii in "
                         "metres, e.g. 0.3e-6")
    sd = KEY_BY_PATH[f"{where}.sd"].number(
        value["sd"], fix="give the standard deviation of the radii in metres (> 0), e.g. 0.3e-6")
    seed = KEY_BY_PATH[f"{where}.seed"].number(value.get("seed", RADIUS_SPREAD_DEFAULTS["seed"]),
                                        fix="give a whole-number seed >= 0")
    spread = RadiusSpread(dist, sd, seed)
    value.clear()
    value.update(distribution=dist, sd=sd, seed=seed)      # the normalised spec
    smallest = min(radii)
    if spread.half_width >= smallest:
        how = (f"{NORMAL_TRUNCATION:g} sd (normal draws are truncated there)" if dist == "normal"
               else "sqrt(3) sd (the uniform half-width)")
        raise SceneError(f"{where}.sd", f"{sd:g} m can make a radius non-positive: draws reach "
                         f"{how} = {spread.half_width:g} m, the smallest radius is {smallest:g} m",
                         f"give sd < {floor_sig(smallest / (spread.half_width / sd)):.2g} m")
    return spread


def drop_unset(spec: dict) -> None:
    """Leave the optional keys that were not given out of the normalised spec."""
    for dotted in OPTIONAL_KEYS:
        section, _, key = dotted.partition(".")
        node = spec.get(section)
        if isinstance(node, dict) and node.get(key) is None:
            node.pop(key, None)
            if not node:
                spec.pop(section)


def given_keys(raw: dict) -> set[str]:
    """Dotted paths of the keys a mapping gives (values not null), before defaults:
    'name', 'gaps', 'gaps.mean', ... Only these can be refused as having no effect."""
    out = set()
    if not isinstance(raw, dict):
        return out
    for key, value in raw.items():
        if value is None:
            continue
        out.add(str(key))
        if isinstance(value, dict) and (isinstance(DEFAULTS.get(key), dict)
                                        or key == "measurement"):
            out |= {f"{key}.{k}" for k, v in value.items() if v is not None}
    return out


def effects_of(value) -> frozenset[str]:
    if isinstance(value, str):
        words = [w for w in re.split(r"[\s,\[\]]+", value) if w]
        if len(words) != 1:
            listed = ", ".join(words or ALWAYS)
            raise SceneError("effects", f"{_short(value)} is one string, not a list",
                             f"write effects: [{listed}]")
        value = words
    if not isinstance(value, list):
        raise SceneError("effects", f"expected a list, got {_short(value)}",
                         f"write effects: [{', '.join(ALWAYS)}, ...]")
    seen = []
    for i, e in enumerate(value):
        KEY_BY_PATH["effects"].choice(e, "effect", field=f"effects[{i}]")
        if e in seen:
            raise SceneError(f"effects[{i}]", f"'{e}' is listed twice (also effects[{seen.index(e)}])",
                             "list each effect once")
        seen.append(e)
    eff = frozenset(seen)
    for e in ALWAYS:
        if e not in eff:
            raise SceneError("effects", f"'{e}' is missing",
                             f"{EFFECT_SPECS[e].always}: add {e}")
    for e, reqs in REQUIRES.items():
        for r, why in reqs:
            if e in eff and r not in eff:
                raise SceneError("effects", f"'{e}' {why} but '{r}' is off",
                                 f"add {r} to effects")
    return eff


def probes_of(value, n: int, given: bool = True) -> tuple[int, int]:
    """The two probe particles (1-based). A two-sphere scene (n = 2) has none: it keeps
    (2, 2), the one sphere struck, for the code that reads the probes, and measures no
    wave (``observables.summarize``); a ``probes`` key it gives is refused."""
    if n == 2:
        if given:
            raise SceneError("probes", "a two-sphere scene has no probes (its collision is "
                             "measured by the restitution)", "drop probes, or give chain.n >= 3")
        return 2, 2
    example = f"write probes: [2, {n}] (two particles from 2 to n = {n}; particle 1 is the striker)"
    if not isinstance(value, list) or len(value) != 2:
        raise SceneError("probes", f"expected a list of exactly two particles, got {_short(value)}",
                         example)
    for i, p in enumerate(value):
        if isinstance(p, bool) or not isinstance(p, int):
            raise SceneError(f"probes[{i}]", f"{_short(p)} is not a particle number",
                             "give whole numbers (1-based)")
        if p == 1:
            raise SceneError(f"probes[{i}]", "particle 1 is the striker",
                             f"give particles from 2 to n = {n}")
        if not 2 <= p <= n:
            raise SceneError(f"probes[{i}]", f"particle {_short(p)} is outside the chain of {n}",
                             f"give particles from 2 to n = {n}")
    p1, p2 = value
    if p2 == p1:
        raise SceneError("probes", f"both probes are particle {p1}", "give two different particles")
    if p2 < p1:
        raise SceneError("probes", f"the second probe ({p2}) is before the first ({p1})",
                         f"list them in the direction the wave travels: probes: [{p2}, {p1}]")
    return p1, p2


# keys that have no effect unless ... (checked only for keys the user wrote)
_SECTION_EFFECT = {m.SECTION: m.SPEC.name for m in SECTIONED}


def refuse_unused(given: set[str], dist: str, eff: frozenset[str], method: str) -> None:
    def refuse(key, why, fix):
        raise SceneError(key, f"has no effect {why}", fix)

    for key in sorted(given):
        section, _, sub = key.partition(".")
        if not sub:
            continue
        if section in _SECTION_EFFECT and _SECTION_EFFECT[section] not in eff:
            refuse(key, f"while {_SECTION_EFFECT[section]} is off",
                   f"add {_SECTION_EFFECT[section]} to effects or drop {key}")
    if "gaps.mean" in given and dist not in ("fixed", "uniform", "exponential"):
        refuse("gaps.mean", f"with distribution '{dist}'",
               "drop it, or use distribution fixed, uniform or exponential")
    if "gaps.values" in given and dist != "list":
        refuse("gaps.values", f"with distribution '{dist}'", "drop it, or use distribution list")
    if "gaps.extra_length" in given and dist != "from_length":
        refuse("gaps.extra_length", f"with distribution '{dist}'",
               "drop it, or use distribution from_length")
    if "gaps.seed" in given and dist not in RANDOM_GAPS:
        refuse("gaps.seed", f"with distribution '{dist}' (nothing is drawn at random)",
               "drop it, or use distribution uniform, exponential or from_length")
    if "integrator.tolerance" in given and method in FIXED_STEP_METHODS:
        refuse("integrator.tolerance", f"with method {method} (a fixed step)",
               "drop it, or use method adaptive, event or auto")


def measurement_of(spec: dict, given: set[str]) -> Measurement | None:
    """The validated measurement block of a merged spec (None without one; the key is
    then dropped from the spec, so an unmeasured scene hashes as before the block
    existed); the spec's block is replaced by its normalised form."""
    block = spec.get("measurement")
    if block is None:
        spec.pop("measurement", None)
        return None
    if not isinstance(block, dict):
        raise SceneError("measurement", f"expected a mapping, got {_short(block)}",
                         "write e.g. measurement: {bandwidth_hz: 2.5e6, filter: bessel}")
    m = merge(MEASUREMENT_DEFAULTS, block, "measurement.")
    spec["measurement"] = m
    bw = number(spec, "measurement.bandwidth_hz",
                fix="give the vibrometer's -3 dB bandwidth in Hz, e.g. 2.5e6")
    kind = KEY_BY_PATH["measurement.filter"].choice(m["filter"], "filter")
    order = number(spec, "measurement.order",
                   fix=f"give the filter order as a whole number from 1 to {MAX_FILTER_ORDER}")
    fs = number(spec, "measurement.sampling_rate_hz",
                fix="give the digitiser's sampling rate in Hz, e.g. 20e6")
    if not fs > 2.0 * bw:
        raise SceneError("measurement.sampling_rate_hz",
                         f"{fs:g} Hz is not above twice the bandwidth {bw:g} Hz",
                         f"give sampling_rate_hz > {2.0 * bw:g} (e.g. {8.0 * bw:g}) or a "
                         "smaller bandwidth_hz")
    noise = number(spec, "measurement.noise_rms_m_s",
                   fix="give the RMS of the additive white noise in m/s (>= 0)")
    seed = number(spec, "measurement.seed", fix="give a whole-number seed >= 0")
    if "measurement.seed" in given and noise == 0:
        raise SceneError("measurement.seed", "has no effect without noise (noise_rms_m_s "
                         "is 0)", "drop it, or give measurement.noise_rms_m_s > 0")
    m.update(bandwidth_hz=bw, order=order, sampling_rate_hz=fs, noise_rms_m_s=noise,
             seed=seed)
    return Measurement(bw, kind, order, fs, noise, seed)


def check_derived(scene) -> None:
    """What the scene's values make of the chain, before it runs: every sphere's mass and
    moment of inertia and every Hertz constant a finite positive number (an extreme radius,
    1e300 m or 1e-200 m, overflows them; materials are bounded by ``materials.FIELDS``); no
    contact and no wall overlapping beyond ``guards.HARD_OVERLAP_RATIO`` of its R* at rest
    or at the fastest striker (``guards.check_overlaps``); each enabled effect's own checks
    (its module's ``check``); and a finite collision time."""
    listed = isinstance(scene.spec["chain"].get("radius"), list)

    def refuse(i: int, problem: str):
        field = ("striker.radius" if i == 0 and "striker.radius" in scene.given else
                 f"chain.radius[{i}]" if listed else "chain.radius")
        raise SceneError(field, f"with radius {scene.radii[i]:g} m {problem}",
                         "give the radius in metres, e.g. 150e-6")

    for i, r in enumerate(scene.radii[:1] if scene.uniform else scene.radii):
        if not r ** 0.5 * r < 1e100:            # r^3 and more would overflow
            refuse(i, f"sphere {i + 1}'s mass and inertia overflow")
    wall = (scene.wall_k,) if scene.wall is not None else ()
    alike = scene.uniform                       # one sphere and one contact stand for all
    for what, values in (("mass", (scene.mass,) if alike else scene.masses),
                         ("moment of inertia", (scene.inertia,) if alike else scene.inertias),
                         ("Hertz constant", ((scene.hertz_k,) if alike else scene.contact_k)
                          + wall)):
        bad = next((i for i, x in enumerate(values) if not (math.isfinite(x) and x > 0)), None)
        if bad is not None:
            where = "contact" if what == "Hertz constant" else "sphere"
            refuse(min(bad, scene.n - 1), f"the {what} of {where} {bad + 1} is "
                   f"{values[bad]:g}, not a finite positive number")
    check_overlaps(scene)
    for m in EFFECT_MODULES:
        if scene.has(m.SPEC.name) and hasattr(m, "check"):
            m.check(scene)
    vmax = max(scene.striker_velocities)
    if vmax > 0:
        try:
            tc = scene.contact_time(vmax)
        except (OverflowError, ZeroDivisionError, ValueError):
            tc = math.nan
        if not (math.isfinite(tc) and tc > 0):
            raise SceneError("striker.velocity", f"at {vmax:g} m/s the collision time is "
                             f"{tc:g}, not a finite positive number",
                             "give the striker's speed in m/s, e.g. 0.1")


def check_sampling(scene) -> None:
    """A given sample interval must resolve the solitary wave of the fastest striker."""
    limit = max_sample_dt(scene) if scene.sample_dt is not None else None
    if limit is None or scene.sample_dt <= limit:
        return
    vmax = max(scene.striker_velocities)
    width = pulse_width(scene.material, scene.radius, 0.64 * vmax)
    raise SceneError("output.sample_dt",
                     f"{scene.sample_dt:g} s cannot resolve the pulse: at {vmax:g} m/s the "
                     f"solitary wave lasts {width:.3g} s and needs >= {MIN_SAMPLES_PER_PULSE} "
                     f"samples (limit {floor_sig(limit):.2g} s)",
                     f"use sample_dt <= {floor_sig(limit):.2g} or sample_dt: auto")


def check_step(scene) -> None:
    """Checks that need the step (none for method auto, whose step is not known here):
    sample no faster than once per step, and a fixed step must resolve the shortest Hertz
    collision the scene can produce."""
    if scene.method == "auto":
        return
    if scene.sample_dt is not None and scene.sample_dt < scene.dt * (1 - 1e-9):
        raise SceneError("output.sample_dt",
                         f"{scene.sample_dt:g} s is shorter than the step {scene.dt:g} s",
                         "sample no faster than once per step")
    if scene.method not in ("rk4", "verlet"):
        return
    vmax = max(scene.striker_velocities)
    if vmax <= 0:
        return
    _check_step(scene.dt, scene.contact_time(vmax), f"a collision at {vmax:g} m/s lasts")
    # an effect with a time scale of its own (a dashpot) bounds the step too
    for m in EFFECT_MODULES:
        if scene.has(m.SPEC.name) and hasattr(m, "time_scale"):
            tau, what = m.time_scale(scene, vmax)
            _check_step(scene.dt, tau, f"{what} at {vmax:g} m/s is")


def _check_step(dt: float, tau: float, what: str) -> None:
    """Refuse a fixed step dt that resolves the time scale tau (s) in fewer than
    MIN_STEPS_PER_CONTACT steps; ``what`` says what tau is ("... lasts", "... is")."""
    limit = tau / MIN_STEPS_PER_CONTACT
    if dt > limit:
        raise SceneError("integrator.dt",
                         f"{dt:g} s is too large: {what} {tau:.3g} s and needs >= "
                         f"{MIN_STEPS_PER_CONTACT} steps (limit {floor_sig(limit):.2g} s)",
                         f"use dt <= {floor_sig(limit):.2g}, or method adaptive")
