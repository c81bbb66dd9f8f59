"""Each physical effect in its own room: the engines are composed from the registry and
name no effect, every effect module has the parts the registry requires, and the
observable rules are written once (``granchain.obsrules``)."""
from __future__ import annotations

import io
import tokenize
from pathlib import Path

import pytest

from granchain.effects import MODULES, spec
from effect_names import ENGINE_SIDE, ROOT, count, files, naming_lines

# The engines and everything of the LAMMPS support, the columns and the reductions name
# no effect at all: reading them you cannot tell which effects exist.
NO_EFFECT = ("granchain/engines", "granchain/lammps", "granchain/columns.py",
             "granchain/reductions")
# The whole engine side (effect_names.ENGINE_SIDE) keeps at most this many
# effect-naming code lines: the Scene's Hertz constants and collision time (scene.py, from
# effects/hertz.py), the scene check naming a bad Hertz constant (scenecheck.py) and the
# guards' messages on the range of Hertz contact theory (guards.py).
ENGINE_SIDE_BUDGET = 15


def test_the_counter_sees_an_effect_named_in_code_not_in_a_comment(tmp_path):
    f = tmp_path / "m.py"
    f.write_text('"""air_drag in a docstring."""\n# groove_friction in a comment\n'
                 "x = terms.air_drag\n"
                 "y = P[P_GROOVE_S]\n"
                 's = f"{a} rolling_friction"\n'
                 "rotational = 1  # a longer word is not an effect\n"
                 "def g():\n    '''hertz in a docstring.'''\n    return G_HERTZ_K\n")
    assert [k for k, _ in naming_lines(f)] == [3, 4, 5, 9]


@pytest.mark.parametrize("where", NO_EFFECT)
def test_no_engine_file_names_an_effect(where):
    found = {str(f.relative_to(ROOT)): [f"{k}: {line.strip()}" for k, line in naming_lines(f)]
             for f in files(where)}
    found = {f: lines for f, lines in found.items() if lines}
    assert not found, found


def test_the_engine_side_names_few_effects():
    per_file = count(*ENGINE_SIDE)
    assert sum(per_file.values()) <= ENGINE_SIDE_BUDGET, per_file


def _required(module) -> list[tuple[str, ...]]:
    """The parts the registry needs of an effect module, from its declaration: each entry
    a tuple of names, one of which the module must have."""
    s = module.SPEC
    need = [("SPEC",), ("build",), ("lammps",)]
    if s.params or s.flags:
        need.append(("kernel",))
    if s.rows:
        need.append(("rows",))
    if s.histories:
        need += [("forces",), ("project",), ("error_scale",)]
    if s.kicked:
        need.append(("energies",))
    if s.work_slot:
        need.append(("forces", "normal"))
    if hasattr(module, "SECTION"):
        need += [("DEFAULTS",), ("KEYS",), ("settings",)]
    return need


def _missing(module) -> list[tuple[str, ...]]:
    return [alt for alt in _required(module) if not any(hasattr(module, p) for p in alt)]


@pytest.mark.parametrize("module", MODULES, ids=lambda m: m.SPEC.name)
def test_every_effect_has_the_parts_the_registry_requires(module):
    assert not _missing(module), f"{module.__name__} lacks one of each of {_missing(module)}"
    for hook in spec.HOOKS:
        fn = getattr(module, hook, None)
        if fn is not None:
            assert getattr(fn, "granchain_compiled", False), f"{module.__name__}.{hook}"


def test_a_module_without_its_law_is_caught():
    """The check above fails for an effect that declares a history and no projection."""
    import types
    fake = types.SimpleNamespace(SPEC=spec.EffectSpec("fake", state=(("L_X", "contact"),)),
                                 build=None, lammps=None, forces=None, error_scale=None)
    assert _missing(fake) == [("project",)]


# The constants of the observable rules: only granchain.obsrules computes with them (the
# rest imports them, or states them in text).
RULE_CONSTANTS = {"PEAK_TOL", "PASS_FRACTION", "ARRIVAL_FRACTION"}
ARITHMETIC = {"*", "/", "+", "-", "<", ">", "<=", ">=", "=="}


def _computes_with(path: Path) -> list[int]:
    """Lines of a file where a rule constant is an operand of arithmetic or a comparison."""
    toks = [t for t in tokenize.generate_tokens(io.StringIO(path.read_text()).readline)
            if t.type not in (tokenize.NL, tokenize.COMMENT)]
    out = []
    for i, t in enumerate(toks):
        if t.type == tokenize.NAME and t.string in RULE_CONSTANTS:
            near = [toks[j].string for j in (i - 1, i + 1) if 0 <= j < len(toks)]
            if any(s in ARITHMETIC for s in near):
                out.append(t.start[0])
    return out


def test_the_observable_rules_are_written_once():
    found = {str(f.relative_to(ROOT)): lines for f in files("granchain")
             if f.name != "obsrules.py" and (lines := _computes_with(f))}
    assert not found, found


def test_the_rule_check_sees_a_restated_rule(tmp_path):
    f = tmp_path / "m.py"
    f.write_text("passed = v < PASS_FRACTION * top\nlevel = (1.0 - PEAK_TOL) * y\n"
                 "note = f'{ARRIVAL_FRACTION:g}'\n")
    assert _computes_with(f) == [1, 2]
