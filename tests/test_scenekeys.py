"""The scene-key declarations (granchain.validate.Key; granchain.scenekeys.KEYS and each effect
module's KEYS) against what the scene loader fills in and accepts, and the reference page
written from them (granchain.scenekeys)."""
from __future__ import annotations

import copy
import math
import re

import pytest

from granchain import scenekeys
from granchain.effects import MODULES
from granchain.errors import SceneError
from granchain.scene import scene_from_dict
from granchain.scenekeys import DEFAULTS, EFFECTS, MEASUREMENT_DEFAULTS, RADIUS_SPREAD_DEFAULTS


def flat_defaults() -> dict:
    """Every scene key and its default: DEFAULTS (each effect's section included), the
    measurement block's keys and the radius spread's."""
    out = {}

    def walk(node, prefix):
        for k, v in node.items():
            if isinstance(v, dict):
                walk(v, f"{prefix}{k}.")
            else:
                out[prefix + k] = v
    walk(DEFAULTS, "")
    walk(MEASUREMENT_DEFAULTS, "measurement.")
    walk(RADIUS_SPREAD_DEFAULTS, "chain.radius_spread.")
    return out


DECLARED = scenekeys.declared()


def test_the_defaults_hold_every_effect_section():
    keys = flat_defaults()
    sectioned = [m for m in MODULES if hasattr(m, "SECTION")]
    assert len(sectioned) >= 4          # groove, drag, contact, rolling at least
    for m in sectioned:
        assert {f"{m.SECTION}.{k}" for k in m.DEFAULTS} <= set(keys), m.__name__


def test_every_scene_key_is_declared_with_doc_and_unit():
    undeclared = sorted(set(flat_defaults()) - set(DECLARED))
    assert not undeclared, f"scene keys without a Key declaration: {undeclared}"
    for path, (key, _) in DECLARED.items():
        assert key.doc.strip(), f"{path}: empty doc"
        assert key.unit.strip(), f"{path}: empty unit"


def test_no_declaration_is_stale():
    stale = sorted(set(DECLARED) - set(flat_defaults()))
    assert not stale, f"declared keys that the scene does not have: {stale}"


def test_an_effects_keys_are_its_own_section():
    for m in MODULES:
        for key in getattr(m, "KEYS", ()):
            assert key.path.startswith(m.SECTION + "."), key.path
            assert DECLARED[key.path][1] == m.SPEC.name


# --- the declared defaults are what the loader fills in ----------------------------------

# every effect on, with the values they require, and both blocks given: each key not given
# here is read from this scene's normalised spec; the given ones from the plain scene {}
# every effect but adhesion, which refuses the default damping model (as LAMMPS does), and
# plastic_contact, which does not act with the contact and rolling friction yet: its keys
# are read from a scene of it alone (APART), as is adhesion.groove, the one adhesion key
# with a default other than null
ALL_ON = {"effects": [e for e in EFFECTS if e not in ("adhesion", "plastic_contact")],
          "rolling": {"k_roll": 1e3}, "damping": {"e": 0.9}, "measurement": {},
          "chain": {"radius_spread": {"sd": 1e-7}}}
APART = {"plasticity.": {"effects": ["hertz", "plastic_contact"]},
         "adhesion.groove": {"effects": ["hertz", "groove_friction", "adhesion"],
                             "adhesion": {"model": "dmt", "surface_energy": 0.1}}}


def given_paths(raw, prefix=""):
    for k, v in raw.items():
        yield prefix + k
        if isinstance(v, dict):
            yield from given_paths(v, f"{prefix}{k}.")


def spec_value(spec, path):
    """The value at a dotted key of a normalised spec; None where the spec leaves an unset
    key out."""
    node = spec
    for p in path.split("."):
        if not isinstance(node, dict) or p not in node:
            return None
        node = node[p]
    return node


@pytest.mark.parametrize("path", [p for p in flat_defaults() if p in DECLARED])
def test_declared_default_is_what_the_loader_fills_in(path):
    """The default the page shows (scenekeys.entries) is the one a scene gets."""
    shown = {key.path: default for key, default, _ in scenekeys.entries()}
    raw = {} if path in set(given_paths(ALL_ON)) else ALL_ON
    raw = next((v for p, v in APART.items() if path.startswith(p)), raw)
    spec = scene_from_dict(copy.deepcopy(raw)).spec
    assert spec_value(spec, path) == shown[path]


# --- the declared bounds are what the validator checks -----------------------------------

# the other keys a key needs to count (its effect on, its distribution or model, its block)
CONTEXT = {
    "chain.radius_spread.": {"chain": {"radius_spread": {"sd": 1e-7}}},
    "gaps.mean": {"gaps": {"distribution": "fixed"}},
    "gaps.seed": {"gaps": {"distribution": "uniform", "mean": 20e-9}},
    "gaps.values": {"gaps": {"distribution": "list"}},
    "gaps.extra_length": {"gaps": {"distribution": "from_length"}},
    "integrator.tolerance": {"integrator": {"method": "adaptive"}},
    "measurement.": {"measurement": {}},
    "measurement.seed": {"measurement": {"noise_rms_m_s": 1e-3}},
    "precompression.force": {"walls": {"end": "rigid"}},
    "groove.": {"effects": ["hertz", "groove_friction"]},
    "drag.": {"effects": ["hertz", "air_drag"]},
    "contact.": {"effects": ["hertz", "rotation", "particle_friction"]},
    "contact.kt": {"effects": ["hertz", "rotation", "particle_friction"],
                   "contact": {"tangential": "linear_history"}},
    "rolling.": {"effects": ["hertz", "rotation", "rolling_friction"],
                 "rolling": {"k_roll": 1e3}},
    "damping.": {"effects": ["hertz", "contact_damping"], "damping": {"e": 0.9}},
    "damping.e": {"effects": ["hertz", "contact_damping"]},
    "damping.eta": {"effects": ["hertz", "contact_damping"],
                    "damping": {"model": "viscoelastic"}},
    "plasticity.": {"effects": ["hertz", "plastic_contact"]},
    "adhesion.": {"effects": ["hertz", "adhesion"],
                  "adhesion": {"model": "dmt", "surface_energy": 0.1}},
}
# a valid value of each key that has no numeric default
SAMPLE = {"chain.radius_spread.sd": 1e-7, "striker.radius": 100e-6, "t_end": 1e-4,
          "output.sample_dt": 1e-8, "integrator.tolerance": 1e-8, "groove.s": 0.5,
          "groove.kt": 1e3, "contact.kt": 1e3, "rolling.k_roll": 1e3, "damping.e": 0.9,
          "damping.eta": 1e3, "precompression.force": 0.01, "plasticity.yield_pressure": 1e9,
          "adhesion.surface_energy": 0.1}
# keys whose value is a list of such numbers: (the list of a value, the field an error names)
LISTS = {"gaps.values": (lambda v: [v] * 14, "gaps.values[0]")}


def scene_with(path: str, value):
    """A scene mapping in which ``path`` counts, with ``value`` there."""
    raw = {}
    for prefix in (p for p in CONTEXT if p.endswith(".") and path.startswith(p)):
        raw.update(copy.deepcopy(CONTEXT[prefix]))
    if path in CONTEXT:
        raw.update(copy.deepcopy(CONTEXT[path]))
    if path in LISTS:
        value = LISTS[path][0](value)
    *sections, name = path.split(".")
    node = raw
    for s in sections:
        node = node.setdefault(s, {})
    node[name] = value
    return raw


def bound_cases():
    """(key path, a value just outside a declared bound, a value inside next to it)."""
    for path, (key, _) in DECLARED.items():
        if not key.bounded:
            continue
        sample = SAMPLE.get(path, DEFAULTS_FLAT.get(path))
        if key.positive:
            yield path, 0.0, sample
        if key.nonneg:
            yield path, -1 if key.integer else -math.ulp(0.0), 0
        if key.lo is not None:
            yield path, key.lo - 1 if key.integer else math.nextafter(key.lo, -math.inf), key.lo
        if key.hi is not None:
            yield path, key.hi + 1 if key.integer else math.nextafter(key.hi, math.inf), key.hi


DEFAULTS_FLAT = flat_defaults()
CASES = list(bound_cases())


def test_every_bounded_key_has_a_case():
    assert {p for p, _, _ in CASES} == {p for p, (k, _) in DECLARED.items() if k.bounded}
    assert all(isinstance(inside, (int, float)) for _, _, inside in CASES)


@pytest.mark.parametrize("path, outside, inside", CASES,
                         ids=[f"{p}={o!r}" for p, o, _ in CASES])
def test_the_validator_checks_the_declared_bounds(path, outside, inside):
    """A value just outside a declared bound is refused naming the key; the bound itself
    (or a valid value, for a strict bound) is accepted."""
    field = LISTS[path][1] if path in LISTS else path
    scene_from_dict(scene_with(path, inside))
    with pytest.raises(SceneError) as err:
        scene_from_dict(scene_with(path, outside))
    assert err.value.field == field


@pytest.mark.parametrize("path", [p for p, (k, _) in DECLARED.items()
                                  if k.choices and p != "effects"])
def test_an_unknown_choice_is_refused_with_the_declared_choices(path):
    key = DECLARED[path][0]
    scene_from_dict(scene_with(path, key.choices[0]))
    with pytest.raises(SceneError) as err:
        scene_from_dict(scene_with(path, "zzz"))
    assert err.value.field == path
    assert err.value.fix == "use one of " + ", ".join(key.choices)


def test_an_unknown_effect_is_refused_with_the_declared_effects():
    with pytest.raises(SceneError) as err:
        scene_from_dict({"effects": ["hertz", "zzz"]})
    assert err.value.field == "effects[1]"
    assert err.value.fix == "use one of " + ", ".join(DECLARED["effects"][0].choices)


# --- the reference page ------------------------------------------------------------------

def test_the_page_has_one_row_per_key_with_its_default():
    page = scenekeys.reference_markdown()
    for key, default, effect in scenekeys.entries():
        rows = [line for line in page.splitlines() if line.startswith(f"| `{key.path}` |")]
        assert len(rows) == 1, key.path
        cells = re.split(r"(?<!\\)\|", rows[0])[1:-1]
        assert cells[4].strip() == (f"`{effect}`" if effect else "always")


def test_the_page_is_well_formed_markdown():
    page = scenekeys.reference_markdown()
    lines = page.splitlines()
    headings = [line for line in lines if line.startswith("#")]
    assert headings[0] == lines[0] and headings[0].startswith("# ")
    assert all(h.startswith("## ") for h in headings[1:])
    assert len(set(headings)) == len(headings)
    width = None
    for line in lines:
        if line.startswith("|"):
            n = len(re.findall(r"(?<!\\)\|", line))
            width = width or n
            assert n == width, line
    assert width, "the page has no table"


def test_an_undeclared_key_stops_the_page(monkeypatch):
    monkeypatch.setitem(DEFAULTS, "undocumented", 1)
    with pytest.raises(LookupError, match="undocumented"):
        scenekeys.reference_markdown()
