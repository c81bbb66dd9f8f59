"""Scenes: one YAML file describes one experiment (SI units throughout).

``load_scene(path, overrides)`` reads, applies ``--set key.sub=value`` overrides,
fills defaults, validates, and returns a frozen :class:`Scene`. Every problem is a
:class:`~granchain.errors.SceneError` naming the field and the fix, on one line.

Defaults and where they come from are listed in ``DEFAULTS`` below and in
docs/scenes.md.
"""
from __future__ import annotations

import copy
import dataclasses
import difflib
import hashlib
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from .errors import SceneError
from .materials import Material, library

EFFECTS = ("hertz", "groove_friction", "air_drag", "rotation", "particle_friction",
           "rolling_friction")
GAP_DISTRIBUTIONS = ("none", "fixed", "uniform", "exponential", "list", "from_length")
METHODS = ("rk4", "verlet", "adaptive", "auto")
TANGENTIAL_MODELS = ("mindlin", "linear_history")

# Default scene: the chapter's packed 440C chain (15 spheres, R = 150 um, v_s = 0.1 m/s,
# RK4 with a 1 ns step). Constants of Eq. 5.1 are the chapter's Chapter-4 values;
# s = sin(90deg/2) for a 90-degree groove (physics.md: chapter 4 is not available).
DEFAULTS: dict[str, Any] = {
    "name": None,                       # defaults to the file stem
    "material": "ss440c",
    "chain": {"n": 15, "radius": 150e-6},
    "striker": {"velocity": 0.1},
    "gaps": {"distribution": "none", "mean": None, "seed": 0, "values": None,
             "extra_length": None},
    "effects": ["hertz"],
    "groove": {"s": None, "angle_deg": 90.0, "mu": 0.293, "g": 9.81, "kt": "mindlin",
               "damping": 1.0},
    "drag": {"T0": 0.052, "L": 2.5e-3, "form": "as_printed"},
    "contact": {"mu_pp": 1.4, "tangential": "mindlin", "kt": None},
    "rolling": {"k_roll": None, "gamma_roll": 0.0, "mu_roll": 0.01},
    "probes": [2, 13],
    "integrator": {"method": "rk4", "dt": 1e-9, "tolerance": None},
    "t_end": "auto",
    "output": {"sample_dt": "auto"},
    "ensemble": {"realisations": 1},
}

# Fewest integration steps that must fit in the shortest Hertz collision of a scene.
MIN_STEPS_PER_CONTACT = 20


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
    groove_s: float
    groove_mu: float
    gravity: float
    groove_kt: float | None          # None: Mindlin stiffness from the material
    groove_damping: float            # stick dashpot as a fraction of critical
    drag_T0: float
    drag_L: float
    drag_form: str
    mu_pp: float
    tangential: str
    contact_kt: float | None
    k_roll: float | None
    gamma_roll: float
    mu_roll: float
    probes: tuple[int, ...]
    method: str
    dt: float
    tolerance: float | None
    t_end: float | None              # None: auto
    sample_dt: float | None          # None: auto
    realisations: int
    spec: dict = field(repr=False, compare=False)   # normalised mapping (for hashing, decks)
    # method auto: the requested relative error on v_g (method, dt, tolerance hold the
    # setting it resolved to; granchain/cost.py resolve_auto)
    auto_tolerance: float | None = None

    # --- derived quantities -------------------------------------------------------------
    @property
    def mass(self) -> float:
        return self.material.rho * 4.0 / 3.0 * math.pi * self.radius**3

    @property
    def inertia(self) -> float:
        return 0.4 * self.mass * self.radius**2

    @property
    def hertz_k(self) -> float:
        """K of f = K delta^(3/2): (4/3) E* sqrt(R*), E* = E/(2(1-nu^2)), R* = R/2."""
        E_star = self.material.E / (2.0 * (1.0 - self.material.nu**2))
        return 4.0 / 3.0 * E_star * math.sqrt(self.radius / 2.0)

    @property
    def has(self):
        return self.effects.__contains__

    @property
    def hash(self) -> str:
        return scene_hash(self.spec)

    def contact_time(self, v: float) -> float:
        """Duration of a head-on Hertz collision of two free spheres at closing speed v."""
        mu = self.mass / 2.0
        delta_m = (5.0 * mu * v * v / (4.0 * self.hertz_k)) ** 0.4
        return 2.9432 * delta_m / v


def scene_hash(spec: dict) -> str:
    blob = json.dumps(spec, sort_keys=True, separators=(",", ":"), default=float)
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


# ---------------------------------------------------------------------------------------
# loading
# ---------------------------------------------------------------------------------------
def load_scene(path: str | Path, overrides: list[str] | tuple[str, ...] = ()) -> Scene:
    path = Path(path)
    if not path.is_file():
        raise SceneError("<file>", f"'{path}' does not exist", "give the path of a scene YAML file")
    try:
        raw = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark else ""
        raise SceneError("<file>", f"'{path}' is not valid YAML{where}",
                         "fix the YAML syntax") from None
    if raw is None:
        raw = {}
    if not isinstance(raw, dict):
        raise SceneError("<file>", "the top level is not a mapping", "write 'key: value' lines")
    raw = apply_overrides(raw, overrides)
    raw.setdefault("name", path.stem)
    return scene_from_dict(raw)


def apply_overrides(raw: dict, overrides) -> dict:
    """Apply ``key.sub=value`` strings; value is parsed as YAML (numbers, lists, ...)."""
    raw = copy.deepcopy(raw)
    for item in overrides:
        if "=" not in item:
            raise SceneError(str(item), "an override must look like key.sub=value",
                             "write e.g. --set striker.velocity=0.05")
        key, _, text = item.partition("=")
        parts = key.strip().split(".")
        try:
            value = yaml.safe_load(text)
        except yaml.YAMLError:
            value = text
        node = raw
        for p in parts[:-1]:
            if not isinstance(node.get(p, {}), dict):
                node[p] = {}
            node = node.setdefault(p, {})
        node[parts[-1]] = value
    return raw


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
                raise SceneError(where, f"expected a mapping, got {value!r}",
                                 f"write e.g. {key}: {{...}}")
            out[key] = _merge(defaults[key], value, where + ".")
        else:
            out[key] = value
    return out


def _num(spec: dict, dotted: str, *, positive=False, nonneg=False, integer=False,
         allow_none=False, lo=None, hi=None, fix=None):
    node: Any = spec
    for p in dotted.split("."):
        node = node[p]
    if node is None and allow_none:
        return None
    if isinstance(node, bool) or not isinstance(node, (int, float)):
        # YAML 1.1 reads "1e-9" (no dot) as a string: accept numeric strings.
        try:
            node = float(node) if not isinstance(node, bool) else None
        except (TypeError, ValueError):
            node = None
        if node is None:
            raise SceneError(dotted, f"expected a number, got {_get(spec, dotted)!r}",
                             fix or "give a number in SI units")
    value = float(node)
    if not math.isfinite(value):
        raise SceneError(dotted, f"{value} is not a finite number", fix or "give a finite number")
    if integer and value != int(value):
        raise SceneError(dotted, f"{value} is not a whole number", fix or "give an integer")
    if positive and value <= 0:
        raise SceneError(dotted, f"{value:g} must be > 0", fix or "give a positive value")
    if nonneg and value < 0:
        raise SceneError(dotted, f"{value:g} must be >= 0", fix or "give a value >= 0")
    if lo is not None and value < lo:
        raise SceneError(dotted, f"{value:g} is below {lo:g}", fix or f"give a value >= {lo:g}")
    if hi is not None and value > hi:
        raise SceneError(dotted, f"{value:g} is above {hi:g}", fix or f"give a value <= {hi:g}")
    return int(value) if integer else value


def _choice(value, field, options, what):
    """A value that must be one of ``options``, with a 'did you mean' on a typo."""
    if value in options:
        return value
    close = difflib.get_close_matches(str(value), options, n=1)
    hint = f"did you mean '{close[0]}'?" if close else f"use one of {', '.join(options)}"
    raise SceneError(field, f"unknown {what} '{value}'", hint)


def _get(spec, dotted):
    node = spec
    for p in dotted.split("."):
        node = node[p]
    return node


def _material(value) -> Material:
    lib = library()
    if isinstance(value, str):
        if value not in lib:
            close = difflib.get_close_matches(value, list(lib), n=1)
            hint = f"did you mean '{close[0]}'?" if close else f"use one of {', '.join(lib)}"
            raise SceneError("material", f"unknown material '{value}'",
                             f"{hint} or give {{E: ..., nu: ..., rho: ...}}")
        return lib[value]
    if isinstance(value, dict):
        extra = set(value) - {"E", "nu", "rho", "name"}
        if extra:
            raise SceneError(f"material.{sorted(extra)[0]}", "unknown key",
                             "a material mapping has E, nu, rho (and optional name)")
        for k in ("E", "nu", "rho"):
            if k not in value:
                raise SceneError(f"material.{k}", "missing", "give E (Pa), nu and rho (kg/m^3)")
        spec = {"material": value}
        E = _num(spec, "material.E", positive=True)
        nu = _num(spec, "material.nu", lo=-0.999, hi=0.4999,
                  fix="a Poisson ratio lies in (-1, 0.5)")
        rho = _num(spec, "material.rho", positive=True)
        return Material(str(value.get("name", "custom")), E, nu, rho)
    raise SceneError("material", f"expected a name or a mapping, got {value!r}",
                     "write material: ss440c or material: {E: 200e9, nu: 0.28, rho: 7800}")


def scene_from_dict(raw: dict) -> Scene:
    spec = _merge(DEFAULTS, raw)
    material = _material(spec["material"])

    n = _num(spec, "chain.n", integer=True, lo=2, fix="a chain needs at least 2 particles")
    radius = _num(spec, "chain.radius", positive=True, fix="give the sphere radius in metres, e.g. 150e-6")

    vel = spec["striker"]["velocity"]
    vlist = vel if isinstance(vel, list) else [vel]
    if not vlist:
        raise SceneError("striker.velocity", "empty list", "give one velocity or a list of them (m/s)")
    velocities = []
    for i, _ in enumerate(vlist):
        sub = {"striker": {"velocity": vlist[i]}}
        velocities.append(_num(sub, "striker.velocity", nonneg=True,
                               fix="the striker moves towards the chain: give a speed >= 0 in m/s"))

    # effects
    effects = spec["effects"]
    if isinstance(effects, str):
        effects = [effects]
    if not isinstance(effects, list):
        raise SceneError("effects", f"expected a list, got {effects!r}", "write effects: [hertz, ...]")
    for e in effects:
        _choice(e, "effects", EFFECTS, "effect")
    eff = frozenset(effects)
    if "hertz" not in eff:
        raise SceneError("effects", "'hertz' is missing", "every chain needs hertz contacts: add hertz")
    for needs_rot in ("particle_friction", "rolling_friction"):
        if needs_rot in eff and "rotation" not in eff:
            raise SceneError("effects", f"'{needs_rot}' acts through torques but 'rotation' is off",
                             "add rotation to effects")

    # gaps
    dist = _choice(spec["gaps"]["distribution"], "gaps.distribution", GAP_DISTRIBUTIONS,
                   "distribution")
    gap_mean = gap_values = extra = None
    if dist in ("fixed", "uniform", "exponential"):
        if spec["gaps"]["mean"] is None:
            raise SceneError("gaps.mean", f"missing for distribution '{dist}'",
                             "give the mean gap in metres, e.g. mean: 20e-9")
        gap_mean = _num(spec, "gaps.mean", nonneg=True, fix="give the mean gap in metres (>= 0)")
    if dist == "list":
        vals = spec["gaps"]["values"]
        if not isinstance(vals, list):
            raise SceneError("gaps.values", "missing or not a list",
                             f"give a list of n-1 = {n - 1} gaps in metres")
        if len(vals) != n - 1:
            raise SceneError("gaps.values", f"has {len(vals)} entries but the chain has {n - 1} contacts",
                             f"give exactly n-1 = {n - 1} gaps")
        gv = []
        for i, g in enumerate(vals):
            gv.append(_num({"g": {str(i): g}}, f"g.{i}", nonneg=True,
                           fix=f"gaps.values[{i}] must be a finite gap >= 0 in metres"))
        gap_values = tuple(gv)
    if dist == "from_length":
        if spec["gaps"]["extra_length"] is None:
            raise SceneError("gaps.extra_length", "missing for distribution 'from_length'",
                             "give the chain's extra length over the packed length in metres, e.g. 6e-6")
        extra = _num(spec, "gaps.extra_length", nonneg=True, fix="give the extra length in metres (>= 0)")
    seed = _num(spec, "gaps.seed", integer=True, nonneg=True, fix="give a whole-number seed >= 0")

    # groove
    if spec["groove"]["s"] is not None:
        s = _num(spec, "groove.s", positive=True, hi=1.0, fix="the groove factor s lies in (0, 1]")
    else:
        ang = _num(spec, "groove.angle_deg", lo=1e-6, hi=180.0, fix="give the groove opening angle in degrees (0, 180]")
        s = math.sin(math.radians(ang) / 2.0)
    groove_mu = _num(spec, "groove.mu", nonneg=True)
    gravity = _num(spec, "groove.g", nonneg=True)
    kt = spec["groove"]["kt"]
    groove_kt = None if kt == "mindlin" else _num(spec, "groove.kt", positive=True,
                                                  fix="give a stiffness in N/m or 'mindlin'")

    groove_damping = _num(spec, "groove.damping", nonneg=True,
                          fix="give the stick damping as a fraction of critical (default 1)")
    T0 = _num(spec, "drag.T0", positive=True)
    L = _num(spec, "drag.L", positive=True)
    form = _choice(spec["drag"]["form"], "drag.form", ("as_printed", "odd"), "form")

    mu_pp = _num(spec, "contact.mu_pp", nonneg=True)
    tangential = _choice(spec["contact"]["tangential"], "contact.tangential", TANGENTIAL_MODELS,
                         "model")
    contact_kt = _num(spec, "contact.kt", positive=True, allow_none=True,
                      fix="give the tangential stiffness in N/m")
    if tangential == "linear_history" and contact_kt is None and "particle_friction" in eff:
        raise SceneError("contact.kt", "missing for tangential: linear_history",
                         "give the tangential spring stiffness in N/m, or use tangential: mindlin")
    k_roll = _num(spec, "rolling.k_roll", positive=True, allow_none=True)
    if "rolling_friction" in eff and k_roll is None:
        raise SceneError("rolling.k_roll", "missing while rolling_friction is on",
                         "give the rolling spring stiffness in N/m")
    gamma_roll = _num(spec, "rolling.gamma_roll", nonneg=True)
    mu_roll = _num(spec, "rolling.mu_roll", nonneg=True)

    # probes
    probes = spec["probes"]
    if not isinstance(probes, list) or len(probes) < 2:
        raise SceneError("probes", f"expected a list of at least two particles, got {probes!r}",
                         "write probes: [2, 13] (1-based; particle 1 is the striker)")
    pr = []
    for i, p in enumerate(probes):
        if isinstance(p, bool) or not isinstance(p, int):
            raise SceneError(f"probes[{i}]", f"{p!r} is not a particle number",
                             "give 1-based whole numbers")
        if not 1 <= p <= n:
            raise SceneError(f"probes[{i}]", f"particle {p} is outside the chain of {n}",
                             f"give numbers from 1 to {n}")
        pr.append(p)
    if pr[1] <= pr[0]:
        raise SceneError("probes", f"the second probe ({pr[1]}) is not after the first ({pr[0]})",
                         "list probes in the direction the wave travels")

    # integrator
    method = _choice(spec["integrator"]["method"], "integrator.method", METHODS, "method")
    dt = _num(spec, "integrator.dt", positive=True, fix="give the time step in seconds, e.g. 1e-9")
    tol = _num(spec, "integrator.tolerance", positive=True, allow_none=True, hi=0.1,
               fix="give a relative tolerance such as 1e-6")
    if method in ("adaptive", "auto") and tol is None:
        tol = 1e-8 if method == "adaptive" else 1e-4
        spec["integrator"]["tolerance"] = tol

    t_end_raw = spec["t_end"]
    t_end = None if t_end_raw == "auto" else _num(spec, "t_end", positive=True,
                                                    fix="give seconds or 'auto'")
    sd = spec["output"]["sample_dt"]
    sample_dt = None if sd == "auto" else _num(spec, "output.sample_dt", positive=True,
                                               fix="give seconds or 'auto'")
    realisations = _num(spec, "ensemble.realisations", integer=True, lo=1,
                        fix="give a whole number of gap realisations >= 1")

    name = spec["name"] if spec["name"] is not None else "scene"
    scene = Scene(
        name=str(name), material=material, n=n, radius=radius,
        striker_velocities=tuple(velocities), gap_distribution=dist, gap_mean=gap_mean,
        gap_seed=seed, gap_values=gap_values, gap_extra_length=extra, effects=eff,
        groove_s=s, groove_mu=groove_mu, gravity=gravity, groove_kt=groove_kt,
        groove_damping=groove_damping,
        drag_T0=T0, drag_L=L, drag_form=form, mu_pp=mu_pp, tangential=tangential,
        contact_kt=contact_kt, k_roll=k_roll, gamma_roll=gamma_roll, mu_roll=mu_roll,
        probes=tuple(pr), method=method, dt=dt, tolerance=tol, t_end=t_end,
        sample_dt=sample_dt, realisations=realisations, spec=spec,
    )
    if method == "auto":
        # the cheapest setting meeting the tolerance on v_g, from the measured cost model
        from .cost import resolve_auto
        m, dt_r, rtol = resolve_auto(scene)
        scene = dataclasses.replace(scene, method=m, dt=dt_r, tolerance=rtol, auto_tolerance=tol)
    if scene.sample_dt is not None and scene.sample_dt < scene.dt * (1 - 1e-9):
        raise SceneError("output.sample_dt",
                         f"{scene.sample_dt:g} s is shorter than the step {scene.dt:g} s",
                         "sample no faster than once per step")
    _check_step(scene)
    return scene


def _check_step(scene: Scene) -> None:
    """A fixed step must resolve the shortest Hertz collision the scene can produce."""
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
                         f"{tc:.3g} s and needs >= {MIN_STEPS_PER_CONTACT} steps",
                         f"use dt <= {limit:.2g}")
