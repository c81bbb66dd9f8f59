"""The reference page of the scene keys, written from the declarations the validator uses.

Every scene key is declared once, as a :class:`~granchain.validate.Key` beside its default:
the scene's own keys in ``granchain.scene.KEYS``, each effect's section in its module's
``KEYS``. The scene checks take their bounds and choices from these declarations, and the
page takes the defaults from ``granchain.scene.DEFAULTS`` (a block's keys from
``BLOCK_DEFAULTS``), so it shows what the loader fills in and accepts.

``reference_markdown()`` returns the page (MyST Markdown); ``python -m granchain.scenekeys``
prints it.
"""
from __future__ import annotations

from typing import Any

from .effects import MODULES
from .scene import BLOCK_DEFAULTS, DEFAULTS, KEYS
from .validate import Key, number_text

INTRO = """\
A scene is one YAML file per experiment, in SI units. Every key is optional; the defaults \
are the chapter's packed 440C chain. Unknown keys are errors (with a "did you mean"), and so \
are a key given twice (its path and line are named) and a key you wrote that has no effect \
with your other settings: each key below says when it counts, and the keys of an effect's \
section are refused while that effect is off. A section set to null (`--set groove=null`) \
falls back to its defaults. Every refusal is one line naming the key and the fix.

Units: `1` is a dimensionless number, `-` a value that is not a number (a name, a choice, \
a mapping). Each section's table is written from the declarations the scene validator \
checks values against (`granchain.scene.KEYS` and each effect module's `KEYS`).
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
                              "default (granchain.scene.KEYS or the effect module's KEYS)")
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
