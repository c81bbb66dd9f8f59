"""Scenes: one YAML file describes one experiment (SI units throughout).

``load_scene(path, overrides)`` reads, applies ``--set key.sub=value`` overrides,
fills defaults, validates, and returns a frozen :class:`Scene`. Every problem is a
:class:`~granchain.errors.SceneError` naming the field and the fix, on one line.
``Scene.derive(...)`` returns a validated copy with some fields changed.

This layer parses and validates only. A scene with ``integrator.method: auto`` keeps
``method == "auto"`` and its tolerance; the step it runs with comes from the cost model
through the run plan (``granchain.runplan.plan_run``), made where a run starts.

Every key's default is in ``granchain.scenekeys.DEFAULTS`` (an effect's section: in its
module), and every key is declared once beside it (``scenekeys.KEYS``; an effect's: its
module's ``KEYS``) with its unit, bounds and meaning: the checks read the bounds from these
declarations, and ``granchain.scenekeys`` writes the reference page of the scene keys from
them.
"""
from __future__ import annotations

import copy
import dataclasses
import difflib
import hashlib
import json
import math
import re
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any


from .errors import SceneError
from .validate import short as _short
from .scenefile import apply_overrides, read_scene_file
from .scenekeys import (ALWAYS, DEFAULT_TOLERANCE, DEFAULTS, FIXED_STEP_METHODS, KEY_BY_PATH,
                        MAX_FILTER_ORDER, MAX_SPHERES, MEASUREMENT_DEFAULTS,
                        MIN_STEPS_PER_CONTACT, NAME_RE, NAME_RULE, NORMAL_TRUNCATION,
                        OPTIONAL_KEYS, RADIUS_SPREAD_DEFAULTS, RANDOM_GAPS, REQUIRES, SECTIONED)
from .guards import (MIN_SAMPLES_PER_PULSE, check_overlaps, floor_sig, max_sample_dt,
                     pulse_width)
from .effects import MODULES as EFFECT_MODULES, SPECS as EFFECT_SPECS, hertz
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


@dataclass(frozen=True)
class Scene:
    name: str
    material: Material
    n: int
    radius: float
    striker_velocities: tuple[float, ...]
    gap_distribution: str
    gap_mean: float | None
    gap_seed: int
    gap_values: tuple[float, ...] | None
    gap_extra_length: float | None
    effects: frozenset[str]
    # (effect, its validated section) of every effect with a scene section, enabled or not
    # (``granchain.effects``: each module's Settings); read them with ``setting``
    settings: tuple[tuple[str, Any], ...]
    probes: tuple[int, ...]
    method: str
    dt: float
    tolerance: float | None
    t_end: float | None              # None: auto
    sample_dt: float | None          # None: auto
    realisations: int
    spec: dict = field(repr=False, compare=False)   # normalised mapping (for hashing, decks)
    # a scene resolved from method auto: the requested relative error on v_g (method, dt,
    # tolerance and the spec's integrator block hold the setting it resolved to)
    auto_tolerance: float | None = None
    # dotted keys the scene file (or a derive) gave, before defaults: 'integrator.dt', ...
    given: frozenset = field(default=frozenset(), repr=False, compare=False)
    # the vibrometer (None: the probes are not measured)
    measurement: Measurement | None = None
    # every sphere's radius (m) and material, particle 1 (the striker) first
    radii: tuple[float, ...] = ()
    materials: tuple[Material, ...] = ()
    wall: Material | None = None           # the end wall (None: free end)
    precompression: float = 0.0            # dead load on particle 2 (N)
    # each member's radii drawn about ``radii`` (None: every member has ``radii``)
    radius_spread: RadiusSpread | None = None

    # --- derived quantities -------------------------------------------------------------
    @property
    def mass(self) -> float:
        """Mass (kg) of a bead of the chain's material and radius (``chain.radius``,
        particle 2's of a list)."""
        return self.material.rho * 4.0 / 3.0 * math.pi * self.radius**3

    @property
    def inertia(self) -> float:
        return 0.4 * self.mass * self.radius**2

    @property
    def hertz_k(self) -> float:
        """K of f = K delta^(3/2): (4/3) E* sqrt(R*), E* = E/(2(1-nu^2)), R* = R/2, for
        two beads of the chain's material and radius."""
        E_star = self.material.E / (2.0 * (1.0 - self.material.nu**2))
        return 4.0 / 3.0 * E_star * math.sqrt(self.radius / 2.0)

    @cached_property
    def uniform(self) -> bool:
        """Are the nominal spheres all alike, the chain's one bead (a radius spread may
        still make each member's differ)?"""
        return (self.radii.count(self.radius) == len(self.radii)
                and self.materials.count(self.material) == len(self.materials))

    @property
    def heterogeneous(self) -> bool:
        """Do the spheres differ (radius or material) from the chain's one bead, or may a
        member's (a radius spread)?"""
        return self.radius_spread is not None or not self.uniform

    @property
    def distinct_contacts(self) -> range:
        """Indices i of the contacts (spheres i+1, i+2; 0-based) that stand for all of them:
        every contact, or for alike spheres the striker's and the next (the others repeat
        the next: the same spheres, the same static overlap)."""
        return range(min(self.n - 1, 2)) if self.uniform else range(self.n - 1)

    def with_radii(self, radii) -> "Scene":
        """This scene with the given radii (a member's draw of a radius spread) and no
        spread: the chain one member runs."""
        radii = tuple(float(r) for r in radii)
        return dataclasses.replace(self, radii=radii, radius=radii[1], radius_spread=None)

    @cached_property
    def masses(self) -> tuple[float, ...]:
        """Each sphere's mass (kg), particle 1 first."""
        if self.uniform:
            return (self.mass,) * self.n
        return tuple(m.rho * 4.0 / 3.0 * math.pi * r**3
                     for m, r in zip(self.materials, self.radii))

    @cached_property
    def inertias(self) -> tuple[float, ...]:
        """Each sphere's moment of inertia (2/5) m R^2 (kg m^2)."""
        if not self.heterogeneous:
            return (self.inertia,) * self.n
        return tuple(0.4 * m * r * r for m, r in zip(self.masses, self.radii))

    @cached_property
    def contact_k(self) -> tuple[float, ...]:
        """K of each contact i, i+1 (n-1 of them): (4/3) E* sqrt(R*) with
        1/E* = (1-nu_i^2)/E_i + (1-nu_j^2)/E_j and R* = R_i R_j / (R_i + R_j)."""
        if self.uniform:
            return (self.hertz_k,) * (self.n - 1)
        return tuple(hertz.constant(self.materials[i], self.radii[i], self.materials[i + 1],
                                    self.radii[i + 1]) for i in range(self.n - 1))

    @property
    def wall_k(self) -> float | None:
        """K of the last sphere on the end wall (R* = R_n), or None without a wall."""
        if self.wall is None:
            return None
        return hertz.constant(self.materials[-1], self.radii[-1], self.wall, math.inf)

    @property
    def static_overlaps(self) -> tuple[tuple[float, ...], float]:
        """Overlaps (m) of the contacts (n-1) and of the wall contact at t = 0: under a
        dead load F0 every contact from particle 2 to the wall carries F0, delta_0 =
        (F0/K)^(2/3); the striker touches particle 2 at zero overlap. Zeros without load."""
        F0 = self.precompression
        if F0 <= 0.0:
            return (0.0,) * (self.n - 1), 0.0
        inner = (0.0,) + tuple((F0 / k) ** (2.0 / 3.0) for k in self.contact_k[1:])
        return inner, (F0 / self.wall_k) ** (2.0 / 3.0)

    @property
    def has(self):
        return self.effects.__contains__

    def setting(self, effect: str):
        """The validated scene section of an effect (its module's ``Settings``)."""
        for name, st in self.settings:
            if name == effect:
                return st
        raise KeyError(f"effect {effect!r} has no scene section")

    @property
    def hash(self) -> str:
        """Hash of the normalised spec; for a scene resolved from method auto, of the spec
        with the resolved integrator block and the requested tolerance."""
        if self.auto_tolerance is None:
            return scene_hash(self.spec)
        integrator = dict(self.spec["integrator"], auto_tolerance=self.auto_tolerance)
        return scene_hash(dict(self.spec, integrator=integrator))

    def derive(self, changes: dict | None = None, /, **dotted) -> "Scene":
        """A new validated scene with some fields of the spec changed.

        Changes are dotted keys (``scene.derive(**{"integrator.method": "verlet",
        "t_end": 1e-5})``) and/or sections given as mappings (``scene.derive({"integrator":
        {"method": "verlet"}, "t_end": 1e-5})`` or ``scene.derive(integrator={...})``): a
        section's mapping changes only the keys it names, the others keep their values.
        Values are as in a scene file; a value of None unsets the key. The new scene is
        validated whole, as ``load_scene`` validates a file giving this scene's keys and
        the changes: every value, and every combination the validator refuses in a file
        (a gap law on a preloaded chain, ...), whichever of its keys the change named. A
        changed key that has no effect for the new settings is refused as in a file; a
        key of this scene that the change leaves without effect (a tolerance when the
        change picks a fixed step) is the change's choice and is not. A scene resolved
        from method auto derives from its resolved setting (the result is a plain scene
        with that integrator)."""
        flat = _flatten(changes or {}) + _flatten(dotted)
        spec = copy.deepcopy(self.spec)
        for key, value in flat:
            parts = str(key).split(".")
            node = spec
            for i, p in enumerate(parts[:-1]):
                if not isinstance(node.get(p, {}), dict):
                    raise SceneError(".".join(parts[:i + 1]), "is not a mapping",
                                     f"change {'.'.join(parts[:i + 1])} as a whole")
                node = node.setdefault(p, {})
            node[parts[-1]] = copy.deepcopy(value)
        changed = {str(k) for k, v in flat if v is not None}
        changed |= {k.partition(".")[0] for k in changed}
        unset = {str(k) for k, v in flat if v is None}
        return _validate(spec, changed, (self.given - unset) | changed)

    def contact_time(self, v: float) -> float:
        """Duration of the shortest collision of the scene at closing speed v: a head-on
        Hertz collision of two free spheres, for every contact of the chain (reduced mass
        m_i m_j/(m_i + m_j)) and of the last sphere on the wall (its own mass); under a
        preload, also half the period pi sqrt(mu/k2) of a preloaded contact's linear
        oscillation (k2 = (3/2) K^(2/3) F0^(1/3))."""
        if not self.heterogeneous and self.wall is None:
            return hertz.contact_time(self.mass / 2.0, self.hertz_k, v)
        ms, ks = self.masses, self.contact_k
        pairs = [(ms[i] * ms[i + 1] / (ms[i] + ms[i + 1]), ks[i])
                 for i in self.distinct_contacts]
        if self.wall is not None:
            pairs.append((ms[-1], self.wall_k))
        tc = min(hertz.contact_time(mu, k, v) for mu, k in pairs)
        F0 = self.precompression
        if F0 > 0.0:
            tc = min([tc] + [math.pi * math.sqrt(mu / (1.5 * k ** (2.0 / 3.0) * F0 ** (1.0 / 3.0)))
                             for mu, k in pairs[1:]])
        return tc

    def pulse_width(self, v_m: float) -> float:
        """Temporal width (s) of the solitary wave at peak particle velocity v_m: about 5
        diameters over Nesterenko's speed, the shortest over the beads' materials and
        radii (particles 2 to n); under a preload at most 5 diameters over the sound
        speed c0 = 2R sqrt(k2/m) of the stiffest preloaded contact."""
        if self.uniform:
            width = float(pulse_width(self.material, self.radius, v_m))
        else:
            width = min(float(pulse_width(m, r, v_m))
                        for m, r in set(zip(self.materials[1:], self.radii[1:])))
        F0 = self.precompression
        if F0 > 0.0:
            ms, rs, ks = self.masses, self.radii, self.contact_k
            for k in self.distinct_contacts[1:]:
                K = ks[k]
                k2 = 1.5 * K ** (2.0 / 3.0) * F0 ** (1.0 / 3.0)
                c0 = 2.0 * rs[k] * math.sqrt(k2 / ms[k])
                width = min(width, 10.0 * rs[k] / c0)
        return width


def _flatten(changes: dict) -> list[tuple[str, Any]]:
    """(dotted key, value) of a changes mapping: a section's mapping (a key whose default
    is a mapping, but not ``material``) gives one entry per key it names."""
    if not isinstance(changes, dict):
        raise SceneError("<derive>", f"changes must be a mapping, got {_short(changes)}",
                         "give {'section': {'key': value}} or dotted keys")
    out = []
    for key, value in changes.items():
        if isinstance(value, dict) and isinstance(DEFAULTS.get(key), dict) and key != "material":
            out += [(f"{key}.{k}", v) for k, v in value.items()]
        else:
            out.append((str(key), value))
    return out


def scene_hash(spec: dict) -> str:
    blob = json.dumps(spec, sort_keys=True, separators=(",", ":"), default=float)
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


def load_scene(path: str | Path, overrides: list[str] | tuple[str, ...] = ()) -> Scene:
    raw = apply_overrides(read_scene_file(path), overrides)
    path = Path(path)
    if raw.get("name") is None:
        if not NAME_RE.fullmatch(path.stem):
            raise SceneError("name", f"not given, and the file name {path.stem!r} is no valid "
                             "scene name", f"give name: in the scene or rename the file ({NAME_RULE})")
        raw["name"] = path.stem
    return scene_from_dict(raw)


def _merge(defaults: dict, given: dict, prefix: str = "") -> dict:
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
            out[key] = _merge(defaults[key], value, where + ".")
        else:
            out[key] = value
    return out


def _num(spec: dict, dotted: str, *, allow_none: bool = False, fix: str | None = None):
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


def _material(value, where: str = "material", *, wall: bool = False) -> Material:
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


def _chain_spheres(spec: dict, n: int, material: Material, given: set[str]):
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
        radii = [_num(spec, "chain.radius", fix=fix)] * n
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
        materials = [_material(m, f"chain.materials[{i}]") for i, m in enumerate(mats)]
    if spec["striker"].get("radius") is not None:
        if isinstance(rad, list):
            raise SceneError("striker.radius", "given beside the chain.radius list, whose "
                             "first entry is already the striker's radius",
                             "drop striker.radius, or set the striker's radius as "
                             "chain.radius[0]")
        radii[0] = _num(spec, "striker.radius",
                        fix="give the striker's radius in metres, e.g. 189e-6")
    if spec["striker"].get("material") is not None:
        if mats is not None:
            raise SceneError("striker.material", "given beside the chain.materials list, "
                             "whose first entry is already the striker's material",
                             "drop striker.material, or set the striker's material as "
                             "chain.materials[0]")
        materials[0] = _material(spec["striker"]["material"], "striker.material")
    return tuple(radii), tuple(materials)


def _radius_spread(value, radii) -> RadiusSpread | None:
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


def _drop_unset(spec: dict) -> None:
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


def _effects(value) -> frozenset[str]:
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


def _probes(value, n: int) -> tuple[int, int]:
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


def _check_unused(given: set[str], dist: str, eff: frozenset[str], method: str) -> None:
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


def scene_from_dict(raw: dict, *, check_unused: bool = True) -> Scene:
    """Validate a scene mapping (SI units) and return the Scene.

    ``check_unused``: refuse keys of ``raw`` that have no effect for its settings. Turn it
    off only to rebuild a scene from a normalised ``Scene.spec`` (which holds every key);
    to change fields of a scene use :meth:`Scene.derive`.
    """
    if not isinstance(raw, dict):
        raise SceneError("<file>", "the top level is not a mapping", "write 'key: value' lines")
    return _validate(raw, given_keys(raw) if check_unused else set())


def _validate(raw: dict, given: set[str], whole: set[str] | None = None) -> Scene:
    """The Scene of a mapping; ``given``: the dotted keys refused if they have no effect;
    ``whole``: every key the scene gives (default ``given``; a derived scene's are its
    base scene's and the changed ones), checked in combination (a preload with gaps, ...)
    and kept as ``Scene.given``."""
    whole = set(given) if whole is None else set(whole)
    spec = _merge(DEFAULTS, raw)
    name = check_name(spec["name"], "name") if spec["name"] is not None else "scene"
    if spec["material"] is None:            # null: the default (e.g. --set material=null)
        spec["material"] = DEFAULTS["material"]
    material = _material(spec["material"])

    n = _num(spec, "chain.n",
             fix=f"a chain needs at least 3 particles (the striker and two probes) and at most "
             f"{MAX_SPHERES}")
    radii, materials = _chain_spheres(spec, n, material, given)
    radius = radii[1]
    if spec["chain"].get("materials") is not None:
        material = materials[1]
    wall = None
    if spec["walls"]["end"] is not None:
        wall = _material(spec["walls"]["end"], "walls.end", wall=True)
    spread = _radius_spread(spec["chain"].get("radius_spread"), radii)
    pre = spec["precompression"]["force"]
    if (not isinstance(pre, bool) and isinstance(pre, (int, float)) and pre == 0
            and "precompression.force" in given):
        raise SceneError("precompression.force", "0 N has no effect (no load on the chain)",
                         "drop precompression; a chain resting on the end wall needs only "
                         "walls.end")
    load = _num(spec, "precompression.force", allow_none=True,
                fix="give the dead load on particle 2 in newtons (> 0)") or 0.0
    for block, fix in (("walls", "give walls: {end: ss440c} (or rigid), or drop walls"),
                       ("precompression", "give precompression: {force: 0.01} (N, with an end "
                                          "wall), or drop precompression")):
        if block in given and raw.get(block) == {}:
            raise SceneError(block, "an empty block has no effect", fix)

    vel = spec["striker"]["velocity"]
    vlist = vel if isinstance(vel, list) else [vel]
    if not vlist:
        raise SceneError("striker.velocity", "empty list", "give one velocity or a list of them (m/s)")
    velocities = []
    for i, v in enumerate(vlist):
        velocities.append(KEY_BY_PATH["striker.velocity"].number(
            v, field=f"striker.velocity[{i}]" if isinstance(vel, list) else "striker.velocity",
            fix="the striker moves towards the chain: give a speed >= 0 in m/s"))

    eff = _effects(spec["effects"])

    # gaps
    dist = KEY_BY_PATH["gaps.distribution"].choice(spec["gaps"]["distribution"], "distribution")
    gap_mean = gap_values = extra = None
    if dist in ("fixed", "uniform", "exponential"):
        if spec["gaps"]["mean"] is None:
            raise SceneError("gaps.mean", f"missing for distribution '{dist}'",
                             "give the mean gap in metres, e.g. mean: 20e-9")
        gap_mean = _num(spec, "gaps.mean", fix="give the mean gap in metres (>= 0)")
    if dist == "list":
        vals = spec["gaps"]["values"]
        if not isinstance(vals, list):
            raise SceneError("gaps.values", "missing or not a list",
                             f"give a list of n-1 = {n - 1} gaps in metres")
        if len(vals) != n - 1:
            raise SceneError("gaps.values", f"has {len(vals)} entries but the chain has {n - 1} contacts",
                             f"give exactly n-1 = {n - 1} gaps")
        gap_values = tuple(KEY_BY_PATH["gaps.values"].number(g, field=f"gaps.values[{i}]",
                                                      fix="give a finite gap >= 0 in metres")
                           for i, g in enumerate(vals))
    if dist == "from_length":
        if spec["gaps"]["extra_length"] is None:
            raise SceneError("gaps.extra_length", "missing for distribution 'from_length'",
                             "give the chain's extra length over the packed length in metres, e.g. 6e-6")
        extra = _num(spec, "gaps.extra_length", fix="give the extra length in metres (>= 0)")
    seed = _num(spec, "gaps.seed", fix="give a whole-number seed >= 0")

    # each effect's own section, validated by its module
    settings = tuple((m.SPEC.name, m.settings(spec[m.SECTION], frozenset(given), m.SPEC.name in eff))
                     for m in SECTIONED)

    pr = _probes(spec["probes"], n)

    # integrator
    method = KEY_BY_PATH["integrator.method"].choice(spec["integrator"]["method"], "method")
    dt = _num(spec, "integrator.dt", fix="give the time step in seconds, e.g. 1e-9")
    tol = _num(spec, "integrator.tolerance", allow_none=True,
               fix="give a relative tolerance such as 1e-6")
    _check_unused(given, dist, eff, method)
    if "precompression.force" in whole or load > 0.0:
        if wall is None:
            raise SceneError("precompression.force", "needs an end wall to push the chain onto",
                             "add walls: {end: ss440c} (or rigid), or drop precompression")
        if dist != "none":
            raise SceneError("precompression.force", f"given together with gaps "
                             f"(distribution '{dist}'): a preloaded chain has no gaps",
                             "drop the gaps block (distribution none) or the precompression")
    if wall is not None and method == "event":
        raise SceneError("integrator.method", "event does not handle an end wall",
                         "use rk4, verlet or adaptive with walls.end")
    if method in DEFAULT_TOLERANCE and tol is None:
        tol = DEFAULT_TOLERANCE[method]
        spec["integrator"]["tolerance"] = tol

    t_end_raw = spec["t_end"]
    t_end = None if t_end_raw == "auto" else _num(spec, "t_end", fix="give seconds or 'auto'")
    sd = spec["output"]["sample_dt"]
    sample_dt = None if sd == "auto" else _num(spec, "output.sample_dt",
                                               fix="give seconds or 'auto'")
    realisations = _num(spec, "ensemble.realisations",
                        fix="give a whole number of gap realisations >= 1")
    measurement = _measurement(spec, given)
    _drop_unset(spec)
    for m in SECTIONED:
        if getattr(m, "SECTION_OPTIONAL", False) and m.SPEC.name not in eff and not any(
                k.startswith(m.SECTION + ".") for k in given):
            spec.pop(m.SECTION, None)
    try:
        scene_hash(spec)
    except (TypeError, ValueError, OverflowError) as exc:
        raise SceneError("<file>", f"a value cannot be stored ({type(exc).__name__})",
                         "give plain numbers, strings and lists") from None

    scene = Scene(
        name=name, material=material, n=n, radius=radius,
        striker_velocities=tuple(velocities), gap_distribution=dist, gap_mean=gap_mean,
        gap_seed=seed, gap_values=gap_values, gap_extra_length=extra, effects=eff,
        settings=settings, probes=tuple(pr), method=method, dt=dt, tolerance=tol, t_end=t_end,
        sample_dt=sample_dt, realisations=realisations, spec=spec, given=frozenset(whole),
        measurement=measurement, radii=radii, materials=materials, wall=wall,
        precompression=load, radius_spread=spread,
    )
    _check_derived(scene)
    check_step(scene)
    _check_sampling(scene)
    return scene


def _measurement(spec: dict, given: set[str]) -> Measurement | None:
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
    m = _merge(MEASUREMENT_DEFAULTS, block, "measurement.")
    spec["measurement"] = m
    bw = _num(spec, "measurement.bandwidth_hz",
              fix="give the vibrometer's -3 dB bandwidth in Hz, e.g. 2.5e6")
    kind = KEY_BY_PATH["measurement.filter"].choice(m["filter"], "filter")
    order = _num(spec, "measurement.order",
                 fix=f"give the filter order as a whole number from 1 to {MAX_FILTER_ORDER}")
    fs = _num(spec, "measurement.sampling_rate_hz",
              fix="give the digitiser's sampling rate in Hz, e.g. 20e6")
    if not fs > 2.0 * bw:
        raise SceneError("measurement.sampling_rate_hz",
                         f"{fs:g} Hz is not above twice the bandwidth {bw:g} Hz",
                         f"give sampling_rate_hz > {2.0 * bw:g} (e.g. {8.0 * bw:g}) or a "
                         "smaller bandwidth_hz")
    noise = _num(spec, "measurement.noise_rms_m_s",
                 fix="give the RMS of the additive white noise in m/s (>= 0)")
    seed = _num(spec, "measurement.seed", fix="give a whole-number seed >= 0")
    if "measurement.seed" in given and noise == 0:
        raise SceneError("measurement.seed", "has no effect without noise (noise_rms_m_s "
                         "is 0)", "drop it, or give measurement.noise_rms_m_s > 0")
    m.update(bandwidth_hz=bw, order=order, sampling_rate_hz=fs, noise_rms_m_s=noise,
             seed=seed)
    return Measurement(bw, kind, order, fs, noise, seed)


def _check_derived(scene: Scene) -> None:
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


def _check_sampling(scene: Scene) -> None:
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


def check_step(scene: Scene) -> None:
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
    tc = scene.contact_time(vmax)
    limit = tc / MIN_STEPS_PER_CONTACT
    if scene.dt > limit:
        raise SceneError("integrator.dt",
                         f"{scene.dt:g} s is too large: a collision at {vmax:g} m/s lasts "
                         f"{tc:.3g} s and needs >= {MIN_STEPS_PER_CONTACT} steps "
                         f"(limit {floor_sig(limit):.2g} s)",
                         f"use dt <= {floor_sig(limit):.2g}, or method adaptive")
    # an effect with a time scale of its own (a dashpot) bounds the step too
    for m in EFFECT_MODULES:
        if scene.has(m.SPEC.name) and hasattr(m, "time_scale"):
            tau, what = m.time_scale(scene, vmax)
            limit = tau / MIN_STEPS_PER_CONTACT
            if scene.dt > limit:
                raise SceneError("integrator.dt",
                                 f"{scene.dt:g} s is too large: {what} at {vmax:g} m/s is "
                                 f"{tau:.3g} s and needs >= {MIN_STEPS_PER_CONTACT} steps "
                                 f"(limit {floor_sig(limit):.2g} s)",
                                 f"use dt <= {floor_sig(limit):.2g}, or method adaptive")
