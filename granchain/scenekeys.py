"""The scene's keys: each key's default and declaration, and the reference page written
from them.

Every scene key is declared once, as a :class:`~granchain.validate.Key` beside its default:
the scene's own keys in ``KEYS`` below (defaults in ``DEFAULTS``, a block's keys in
``BLOCK_DEFAULTS``), each effect's section in its module's ``KEYS`` and ``DEFAULTS``. The
scene checks (``granchain.scenecheck``) take their bounds and choices from these
declarations, and the page takes the defaults from ``DEFAULTS``, so it shows what the
loader fills in and accepts.

``reference_markdown()`` returns the page (MyST Markdown); ``python -m granchain.scenekeys``
prints it.
"""
from __future__ import annotations

import re
from typing import Any

from .effects import MODULES
from .guards import HARD_OVERLAP_RATIO, MAX_OVERLAP_RATIO, MIN_SAMPLES_PER_PULSE
from .materials import FIELDS
from .validate import Key, number_text

EFFECTS = tuple(m.SPEC.name for m in MODULES)
# the effects every scene has, and each effect's requirements (their EffectSpecs)
ALWAYS = tuple(m.SPEC.name for m in MODULES if m.SPEC.always)
REQUIRES = {m.SPEC.name: m.SPEC.requires for m in MODULES if m.SPEC.requires}
# effect -> its scene section, for the effects that have one (granchain.effects: each
# declares SECTION, its DEFAULTS and validates it with ``settings``)
SECTIONED = tuple(m for m in MODULES if hasattr(m, "SECTION"))
GAP_DISTRIBUTIONS = ("none", "fixed", "uniform", "exponential", "list", "from_length")
METHODS = ("rk4", "verlet", "adaptive", "event", "auto")
FIXED_STEP_METHODS = ("rk4", "verlet")        # dt is the step
TOLERANCE_METHODS = ("adaptive", "event")     # the step follows integrator.tolerance

# Default scene: the chapter's packed 440C chain (15 spheres, R = 150 um, v_s = 0.1 m/s,
# RK4 with a 1 ns step). Constants of Eq. 5.1 are the chapter's Chapter-4 values;
# s = sin(90deg/2) for a 90-degree groove (the thesis's chapter 4, which fixes s, is not available).
DEFAULTS: dict[str, Any] = {
    "name": None,                       # defaults to the file stem
    "material": "ss440c",
    # chain.radius: one radius, or a list of n (particle 1 is the striker);
    # chain.materials: a list of n materials (default: every sphere is `material`);
    # chain.radius_spread: each member's radii drawn about the nominal ones
    "chain": {"n": 15, "radius": 150e-6, "materials": None, "radius_spread": None},
    # striker.radius / striker.material: particle 1's own (default: as the chain gives)
    "striker": {"velocity": 0.1, "radius": None, "material": None},
    "gaps": {"distribution": "none", "mean": None, "seed": 0, "values": None,
             "extra_length": None},
    "effects": list(ALWAYS),
    # each effect's own section (groove, drag, contact, rolling), from its module
    **{m.SECTION: m.DEFAULTS for m in SECTIONED},
    "probes": [2, 13],
    "integrator": {"method": "rk4", "dt": 1e-9, "tolerance": None},
    "t_end": "auto",
    "output": {"sample_dt": "auto"},
    "ensemble": {"realisations": 1},
    # the virtual laser vibrometer (granchain.vibrometer); None: the scene is not
    # measured. A given block is filled from MEASUREMENT_DEFAULTS.
    "measurement": None,
    # a flat wall touching the last sphere: a material (name or {E, nu}) or 'rigid';
    # None: the far end is free (the chapter's chain)
    "walls": {"end": None},
    # a dead load (N) on particle 2 pushing the chain onto the end wall; the chain starts
    # at its static overlaps
    "precompression": {"force": None},
}

# Keys that are left out of a scene's normalised spec when not given, so that a scene
# using none of them keeps the hash it had before they existed.
OPTIONAL_KEYS = ("chain.materials", "chain.radius_spread", "striker.radius", "striker.material", "walls.end",
                 "precompression.force")

# Defaults of the measurement block. The chapter's vibrometers have a 2.5 MHz bandwidth;
# their decoders' filter response is not given, so butterworth and bessel are offered
# (order 4 by default). 20 MS/s is a typical digitiser rate for a 2.5 MHz signal (8x the
# bandwidth). noise_rms_m_s: additive white noise on the recorded samples (none by
# default); seed: its random stream.
MEASUREMENT_DEFAULTS: dict[str, Any] = {
    "bandwidth_hz": 2.5e6,
    "filter": "butterworth",
    "order": 4,
    "sampling_rate_hz": 20e6,
    "noise_rms_m_s": 0.0,
    "seed": 0,
}
FILTERS = ("butterworth", "bessel")
MAX_FILTER_ORDER = 10

# Fewest integration steps that must fit in the shortest Hertz collision of a scene (the
# step guard; the accuracy study's coarsest setting).
MIN_STEPS_PER_CONTACT = 20
# The longest chain a scene may describe (each sphere has its own radius and material)
MAX_SPHERES = 1_000_000
# Fewest samples per solitary-wave width that output.sample_dt must give:
# MIN_SAMPLES_PER_PULSE (granchain/guards.py).

# Names (scene name, file stem, custom material name) reach deck comments, data-file
# titles, JSON and logs: only these characters, 1 to 64 of them.
# Names reach decks, data files, paths and shells: a safe set, no leading '.' or '-'
NAME_RE = re.compile(r"[A-Za-z0-9_][A-Za-z0-9._-]{0,63}")
NAME_RULE = "use 1-64 characters from A-Z a-z 0-9 . _ -, starting with a letter, digit or _"
# the distributions that draw at random (gaps.seed matters only for these)
RANDOM_GAPS = ("uniform", "exponential", "from_length")
# integrator.tolerance when not given, by method (the fixed-step methods have none)
DEFAULT_TOLERANCE = {"adaptive": 1e-8, "event": 1e-6, "auto": 1e-4}

RADIUS_SPREADS = ("normal", "uniform")
# a normal spread is drawn truncated at this many sd (a draw beyond it is drawn again)
NORMAL_TRUNCATION = 4.0
# Defaults of a chain.radius_spread block (sd has none: a given block must give it)
RADIUS_SPREAD_DEFAULTS: dict[str, Any] = {"distribution": "normal", "sd": None, "seed": 0}

# The blocks whose key defaults to null and whose given mapping is filled from defaults
# of its own
BLOCK_DEFAULTS = {"chain.radius_spread": RADIUS_SPREAD_DEFAULTS,
                  "measurement": MEASUREMENT_DEFAULTS}

_MATERIAL = ("a name from `granchain/data/materials.yaml`, or a mapping `{E: 200e9, nu: 0.28, "
             "rho: 7800}` (" + ", ".join(k.range_text.strip("`") + ("" if k.unit == "1" else
                                                                   f" {k.unit}")
                                         for k in FIELDS.values())
             + "; an optional `name`)")

# Each key of DEFAULTS, MEASUREMENT_DEFAULTS and RADIUS_SPREAD_DEFAULTS, declared once (an
# effect's section: its module's KEYS). The scene's checks (granchain.scenecheck) take the
# bounds and choices from here; reference_markdown() below writes the page from here.
KEYS: tuple[Key, ...] = (
    Key("name", "-", "The scene's name, written into deck comments, data-file titles and file "
        "names. null: the scene file's stem (`scene` for a scene given as a mapping).",
        allowed=NAME_RULE.removeprefix("use ")),
    Key("material", "-", "The material of the spheres. The library has 316 and 440C stainless, "
        "brass, aluminium 6061, 52100 chrome steel, tungsten carbide, PTFE and soda-lime "
        "glass, each with its source; E, nu, rho of 316 and 440C are handbook values (the "
        "thesis's Table 2.1 is not available). null: the default. Refused beside a "
        "`chain.materials` list.", allowed=_MATERIAL),
    Key("chain.n", "1", "Number of spheres, particle 1 (the striker) included. 2: the "
        "two-sphere collision, the restitution experiment (no probes; its result gives the "
        "measured restitution and whether the pair was captured); from 3: a chain with two "
        "probes.", integer=True, lo=2, hi=MAX_SPHERES),
    Key("chain.radius", "m", "Sphere radius (the chapter's). A list gives each sphere its "
        "own, particle 1 (the striker) first: dimer, tapered and impurity chains. Every "
        "contact is Hertzian with 1/E* = (1-nu_i^2)/E_i + (1-nu_j^2)/E_j and R* = R_i R_j/(R_i "
        "+ R_j); the other effects use each sphere's own mass, radius and "
        "inertia.", positive=True, allowed="or a list of n radii"),
    Key("chain.materials", "-", "Each sphere's material, particle 1 first (one material for "
        "every sphere: `material`, which is refused beside the list, as is "
        "`striker.material`). null: every sphere is `material`.",
        allowed="a list of n materials, each as `material`"),
    Key("chain.radius_spread", "-", "Each member's radii drawn about the nominal ones "
        "(`chain.radius_spread.*` below), from a stream of its own, so a member re-runs alone "
        "bit for bit; both engines take it. null: every member has the nominal radii.",
        allowed="a mapping, or null"),
    Key("chain.radius_spread.distribution", "-", f"`normal`: truncated at "
        f"{NORMAL_TRUNCATION:g} sd (a draw beyond is drawn again); `uniform`: on +-sqrt(3) sd. "
        "Member r draws from rng([seed, r, RADIUS_STREAM]).", choices=RADIUS_SPREADS),
    Key("chain.radius_spread.sd", "m", "Standard deviation of the radii; required in a "
        "given block.", positive=True, allowed="a draw must not reach a non-positive radius: "
        f"{NORMAL_TRUNCATION:g} sd (normal) or sqrt(3) sd (uniform) below the smallest radius"),
    Key("chain.radius_spread.seed", "1", "Seed of the radius draws.", integer=True,
        nonneg=True),
    Key("striker.velocity", "m/s", "The striker's speed towards the chain (the chapter's); a "
        "list is a sweep, one run per speed.", nonneg=True, allowed="or a list of speeds; "
        f"every contact's peak overlap bound within {HARD_OVERLAP_RATIO:g} R* (warned above "
        f"{MAX_OVERLAP_RATIO:g} R*)"),
    Key("striker.radius", "m", "Particle 1's own radius: a heavy or light striker, beside one "
        "`chain.radius` (refused beside a list, whose first entry is the striker's). null: as "
        "`chain.radius` gives.", positive=True),
    Key("striker.material", "-", "Particle 1's own material, beside `material` (refused beside "
        "a `chain.materials` list, whose first entry is the striker's). null: as `material` "
        "gives.", allowed="as `material`"),
    Key("gaps.distribution", "-", "The gaps between neighbours (n-1 of them): `none`, a "
        "packed chain; `fixed`, every gap `mean`; `uniform`, i.i.d. U(0, 2 mean) (the chapter "
        "says \"random\"); `exponential`, i.i.d. with mean `mean`; `list`, the n-1 `values`; "
        "`from_length`, the chain longer than packed by `extra_length`, split at random "
        "over the contacts (flat Dirichlet; the chapter's Fig. 5.4).",
        choices=GAP_DISTRIBUTIONS),
    Key("gaps.mean", "m", "The mean gap of `fixed`, `uniform` and `exponential` (required "
        "there, refused with the others).", nonneg=True),
    Key("gaps.seed", "1", "Seed of the random gaps (`uniform`, `exponential`, `from_length`; "
        "refused with the others): realisation r draws from rng([seed, r]), so any member "
        "re-runs alone bit for bit.", integer=True, nonneg=True),
    Key("gaps.values", "m", "The n-1 gaps of `list` (required there, refused with the "
        "others), the same for every realisation.", nonneg=True,
        allowed="a list of n-1 gaps, each so"),
    Key("gaps.extra_length", "m", "The length by which the chain exceeds the packed length, "
        "for `from_length` (required there, refused with the others): every realisation has "
        "total gap `extra_length`.", nonneg=True),
    Key("effects", "-", "The physical effects of the chapter's Eq. 5.1 that act; "
        + "; ".join([f"`{e}` is always on" for e in ALWAYS]
                    + [f"`{e}` {why}, so it needs `{r}`" for e, reqs in REQUIRES.items()
                       for r, why in reqs]) + ".",
        choices=EFFECTS, allowed="a list of these, each once"),
    Key("probes", "1", "The two particles whose velocities are recorded and compared (the "
        "chapter's), in the direction the wave travels; particle 1 is the striker. A "
        "two-sphere scene has none (refused there; its probe observables are null).",
        allowed="two particles p1, p2 with 2 <= p1 < p2 <= n"),
    Key("integrator.method", "-", "`rk4` and `verlet`: a fixed step `dt` (the chapter's RK4); "
        "`adaptive` (DOP853) and `event` (event-driven; no end wall): the step follows "
        "`tolerance`; `auto`: the cheapest setting the cost model expects to reach "
        "`tolerance`, the relative error on v_g (the event method alone where a contact "
        "law switches that the model did not measure).", choices=METHODS),
    Key("integrator.dt", "s", "The step of `rk4` and `verlet` (the chapter's). It must give "
        f"at least {MIN_STEPS_PER_CONTACT} steps per shortest collision at the fastest "
        "striker (and per dashpot time m_eff/eta with contact damping); the error shows the "
        "limit.", positive=True),
    Key("integrator.tolerance", "1", "The relative tolerance of `adaptive` and `event`, or of "
        "`auto` the requested relative error on v_g; refused with `rk4` and `verlet`. null: "
        + ", ".join(f"{number_text(t)} for {m}" for m, t in DEFAULT_TOLERANCE.items()) + ".",
        positive=True, hi=0.1),
    Key("t_end", "s", "How long a run lasts. `auto`: until the wave has left the whole chain "
        "(with an end wall, until the last sphere moves back from the wall faster than it "
        "arrived and is behind its starting position).", positive=True, allowed="or `auto`"),
    Key("output.sample_dt", "s", "The interval of the recorded samples. It must give at least "
        f"{MIN_SAMPLES_PER_PULSE} samples per solitary-wave width at the fastest striker, and "
        "be no shorter than the step. `auto`: `granchain.stoprule.SAMPLES_PER_PULSE` samples "
        "per width.", positive=True, allowed="or `auto`"),
    Key("ensemble.realisations", "1", "The number of gap realisations; realisation r draws "
        "from rng([gaps.seed, r]).", integer=True, lo=1),
    Key("measurement", "-", "The virtual laser vibrometer (`measurement.*` below): each probe's "
        "velocity is resampled onto the digitiser's grid, low-pass filtered (causal, from "
        "rest) and given noise, and the peaks, delays and v_g are read from that record as "
        "the experiment reads them (`*_measured` fields and columns). null: the probes are "
        "not measured. A given block is filled from the defaults below.",
        allowed="a mapping, or null"),
    Key("measurement.bandwidth_hz", "Hz", "The vibrometer's -3 dB bandwidth (the chapter's "
        "vibrometers').", positive=True),
    Key("measurement.filter", "-", "The decoder's low-pass: the analog prototype of this "
        "kind, made digital by the bilinear transform with the bandwidth pre-warped; the "
        "chapter does not give the response, so both are offered. A causal filter delays "
        "each pulse, which cancels in the probe-to-probe delay.", choices=FILTERS),
    Key("measurement.order", "1", "The filter's order.", integer=True, lo=1,
        hi=MAX_FILTER_ORDER),
    Key("measurement.sampling_rate_hz", "Hz", "The digitiser's rate (by default 8 x the "
        "bandwidth, a typical rate for it).", positive=True,
        allowed="above 2 x `bandwidth_hz`"),
    Key("measurement.noise_rms_m_s", "m/s", "RMS of the white noise added to the recorded "
        "samples.", nonneg=True),
    Key("measurement.seed", "1", "Seed of the noise: member i draws from rng([seed, i]); "
        "refused without noise.", integer=True, nonneg=True),
    Key("walls.end", "-", "A flat wall touching the last sphere (R* = R_n; `rigid`: 1/E_w = 0); "
        "its force is recorded (`wall_force_max`, `t_wall_peak`, `wall_force_static`). The "
        "event method takes no wall. null: the far end is free (the chapter's chain).",
        allowed="a material name, a mapping `{E, nu}`, or `rigid`"),
    Key("precompression.force", "N", "A dead load F0 on particle 2 pushing the chain onto the "
        "end wall (needs `walls.end`, no gaps). The chain starts at rest in its static state, "
        "every contact from particle 2 to the wall overlapping by (F0/K)^(2/3); the ledger's "
        "`work_load` is the load's work. null: no load (0 is refused: a key with no "
        "effect).", positive=True,
        allowed=f"static overlaps within {HARD_OVERLAP_RATIO:g} R* of each contact (warned "
        f"above {MAX_OVERLAP_RATIO:g} R*)"),
)
# the declaration of each of the scene's own keys, by dotted path
KEY_BY_PATH = {k.path: k for k in KEYS}


INTRO = """\
A scene is one YAML file per experiment, in SI units. Every key is optional; the defaults \
are the chapter's packed 440C chain. Unknown keys are errors (with a "did you mean"), and so \
are a key given twice (its path and line are named) and a key you wrote that has no effect \
with your other settings: each key below says when it counts, and the keys of an effect's \
section are refused while that effect is off. A section set to null (`--set groove=null`) \
falls back to its defaults. Every refusal is one line naming the key and the fix.

Units: `1` is a dimensionless number, `-` a value that is not a number (a name, a choice, \
a mapping). Each section's table is written from the declarations the scene validator \
checks values against (`granchain.scenekeys.KEYS` and each effect module's `KEYS`).
"""


def declared() -> dict[str, tuple[Key, str | None]]:
    """Every declared scene key by dotted path, with the effect whose section holds it
    (None: a key of the scene itself, always used)."""
    out: dict[str, tuple[Key, str | None]] = {k.path: (k, None) for k in KEYS}
    for m in MODULES:
        out.update((k.path, (k, m.SPEC.name)) for k in getattr(m, "KEYS", ()))
    return out


def _leaves(defaults: dict, prefix: str = "") -> list[tuple[str, Any]]:
    """(dotted path, default) of every key of a defaults mapping, in its order; a block
    whose key defaults to null (``BLOCK_DEFAULTS``) is followed by its own keys."""
    out = []
    for name, value in defaults.items():
        path = prefix + name
        if isinstance(value, dict):
            out += _leaves(value, path + ".")
            continue
        out.append((path, value))
        if path in BLOCK_DEFAULTS:
            out += _leaves(BLOCK_DEFAULTS[path], path + ".")
    return out


def entries() -> list[tuple[Key, Any, str | None]]:
    """(declaration, default, effect or None) of every scene key, in the order of
    ``DEFAULTS``. A key without a declaration is an error."""
    keys = declared()
    out = []
    for path, default in _leaves(DEFAULTS):
        if path not in keys:
            raise LookupError(f"scene key {path} has no declaration: add its Key beside its "
                              "default (granchain.scenekeys.KEYS or the effect module's KEYS)")
        key, effect = keys[path]
        out.append((key, default, effect))
    return out


def _value_text(value) -> str:
    """A default as a scene file writes it (YAML)."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return number_text(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_value_text(v) for v in value) + "]"
    return str(value)


def _cell(text: str) -> str:
    """Table-cell text: one line, ``|`` escaped."""
    return " ".join(text.split()).replace("|", "\\|")


def reference_markdown() -> str:
    """The reference page of every scene key (MyST Markdown): one section per scene
    section, each a table of its keys with default, unit, values, effect and meaning."""
    groups: dict[str, list[tuple[Key, Any, str | None]]] = {}
    for key, default, effect in entries():
        groups.setdefault(key.path.rpartition(".")[0], []).append((key, default, effect))
    lines = ["# Scene keys", "", INTRO.rstrip()]
    for section, rows in groups.items():
        lines += ["", f"## `{section}`" if section else "## Top-level keys", ""]
        effects = sorted({e for _, _, e in rows if e})
        if effects:
            lines += [f"Used with effect `{effects[0]}` (in `effects`): these keys are refused "
                      "while it is off.", ""]
        lines += ["| Key | Default | Unit | Values | Effect | Meaning |",
                  "| --- | --- | --- | --- | --- | --- |"]
        for key, default, effect in rows:
            cells = (f"`{key.path}`", f"`{_value_text(default)}`", key.unit,
                     key.range_text or "any", f"`{effect}`" if effect else "always", key.doc)
            lines.append("| " + " | ".join(_cell(c) for c in cells) + " |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    print(reference_markdown(), end="")
