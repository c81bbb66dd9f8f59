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
them. The checks of each value, of the keys that have no effect and of what the values make
of the chain are ``granchain.scenecheck``'s; this module assembles the :class:`Scene` from
them.
"""
from __future__ import annotations

import copy
import dataclasses
import hashlib
import json
import math
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

from .errors import SceneError
from .validate import short as _short
from .scenefile import apply_overrides, read_scene_file
from .scenekeys import (DEFAULT_TOLERANCE, DEFAULTS, KEY_BY_PATH, MAX_SPHERES, NAME_RE,
                        NAME_RULE, SECTIONED)
from .scenecheck import (Measurement, RadiusSpread, chain_spheres, check_derived, check_name,
                         check_sampling, check_step, drop_unset, effects_of, given_keys,
                         material_of, measurement_of, merge, number, probes_of,
                         radius_spread_of, refuse_unused)
from .guards import pulse_width
from .effects import hertz
from .materials import Material


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
    spec = merge(DEFAULTS, raw)
    name = check_name(spec["name"], "name") if spec["name"] is not None else "scene"
    if spec["material"] is None:            # null: the default (e.g. --set material=null)
        spec["material"] = DEFAULTS["material"]
    material = material_of(spec["material"])

    n = number(spec, "chain.n",
               fix=f"give 2 (a two-sphere collision) or a chain of at least 3 particles (the striker "
               f"and two probes), at most "
               f"{MAX_SPHERES}")
    radii, materials = chain_spheres(spec, n, material, given)
    radius = radii[1]
    if spec["chain"].get("materials") is not None:
        material = materials[1]
    wall = None
    if spec["walls"]["end"] is not None:
        wall = material_of(spec["walls"]["end"], "walls.end", wall=True)
    spread = radius_spread_of(spec["chain"].get("radius_spread"), radii)
    pre = spec["precompression"]["force"]
    if (not isinstance(pre, bool) and isinstance(pre, (int, float)) and pre == 0
            and "precompression.force" in given):
        raise SceneError("precompression.force", "0 N has no effect (no load on the chain)",
                         "drop precompression; a chain resting on the end wall needs only "
                         "walls.end")
    load = number(spec, "precompression.force", allow_none=True,
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

    eff = effects_of(spec["effects"])

    # gaps
    dist = KEY_BY_PATH["gaps.distribution"].choice(spec["gaps"]["distribution"], "distribution")
    gap_mean = gap_values = extra = None
    if dist in ("fixed", "uniform", "exponential"):
        if spec["gaps"]["mean"] is None:
            raise SceneError("gaps.mean", f"missing for distribution '{dist}'",
                             "give the mean gap in metres, e.g. mean: 20e-9")
        gap_mean = number(spec, "gaps.mean", fix="give the mean gap in metres (>= 0)")
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
        extra = number(spec, "gaps.extra_length",
                       fix="give the extra length in metres (>= 0)")
    seed = number(spec, "gaps.seed", fix="give a whole-number seed >= 0")

    # each effect's own section, validated by its module
    settings = tuple((m.SPEC.name, m.settings(spec[m.SECTION], frozenset(given), m.SPEC.name in eff))
                     for m in SECTIONED)

    pr = probes_of(spec["probes"], n, "probes" in given)
    if n == 2:
        spec.pop("probes", None)            # a two-sphere scene has none

    # integrator
    method = KEY_BY_PATH["integrator.method"].choice(spec["integrator"]["method"], "method")
    dt = number(spec, "integrator.dt", fix="give the time step in seconds, e.g. 1e-9")
    tol = number(spec, "integrator.tolerance", allow_none=True,
                 fix="give a relative tolerance such as 1e-6")
    refuse_unused(given, dist, eff, method)
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
    t_end = None if t_end_raw == "auto" else number(spec, "t_end", fix="give seconds or 'auto'")
    sd = spec["output"]["sample_dt"]
    sample_dt = None if sd == "auto" else number(spec, "output.sample_dt",
                                                 fix="give seconds or 'auto'")
    realisations = number(spec, "ensemble.realisations",
                          fix="give a whole number of gap realisations >= 1")
    measurement = measurement_of(spec, given)
    if n == 2 and measurement is not None:
        raise SceneError("measurement", "a two-sphere scene has no probes to record",
                         "drop measurement, or give chain.n >= 3")
    drop_unset(spec)
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
    check_derived(scene)
    check_step(scene)
    check_sampling(scene)
    return scene

