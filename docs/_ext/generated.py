"""Reference pages generated from the code at build time, so they cannot drift from it.

- ``reference/scene.md``: every scene key, from ``granchain.scenekeys.reference_markdown()``;
- ``reference/tables.md``: every table column and JSON key, from
  ``granchain.tables.column_reference_markdown()``;
- ``reference/config.md``: the workflow configuration, rendered from
  ``workflow/schemas/config.schema.yaml`` (each property: type, default, description).

A page whose generator the installed package does not have is not written (Sphinx then
names the missing page). Pages are rewritten only when their text changes, so an
unchanged page does not trigger a rebuild.
"""
from __future__ import annotations

import importlib
from pathlib import Path

import yaml

DOCS = Path(__file__).resolve().parents[1]
ROOT = DOCS.parent
SCHEMA = ROOT / "workflow" / "schemas" / "config.schema.yaml"
# page -> (module, function, title, lead paragraph)
FROM_CODE = {
    "reference/scene.md": (
        "granchain.scenekeys", "reference_markdown", "Scene keys",
        "Every key of a scene file, its type, default and meaning, as "
        "`granchain.scene` reads it. Prose on scenes: [Scenes](../explanation/scenes.md)."),
    "reference/tables.md": (
        "granchain.tables", "column_reference_markdown", "Table columns and JSON keys",
        "The columns of the workflow's tables and the keys of `granchain run --json`, "
        "as `granchain.tables` writes them."),
}
GENERATED = [*FROM_CODE, "reference/config.md"]


def _write(page: str, text: str) -> None:
    path = DOCS / page
    if not path.exists() or path.read_text(encoding="utf-8") != text:
        path.write_text(text, encoding="utf-8")


def _cell(text) -> str:
    """One Markdown table cell: no line breaks, no unescaped pipes, and outside code spans
    no ``<`` that Markdown would read as HTML (``results/<preset>/``)."""
    parts = " ".join(str(text).split()).replace("|", "\\|").split("`")
    return "`".join(p if i % 2 else p.replace("<", "\\<") for i, p in enumerate(parts))


def _type(node: dict, defs: dict) -> str:
    node = _resolve(node, defs)
    if "enum" in node:
        return " or ".join(f"`{v}`" for v in node["enum"])
    if "oneOf" in node or "anyOf" in node:
        return " or ".join(_type(n, defs) for n in node.get("oneOf", node.get("anyOf")))
    t = node.get("type", "")
    t = " or ".join(t) if isinstance(t, list) else t
    if t == "array" and isinstance(node.get("items"), dict):
        inner = _type(node["items"], defs)
        return f"list of {inner}" if inner else "list"
    return t


def _bounds(node: dict) -> str:
    parts = []
    for key, sign in (("minimum", ">="), ("exclusiveMinimum", ">"), ("maximum", "<="),
                      ("exclusiveMaximum", "<"), ("minItems", "items >="),
                      ("maxItems", "items <=")):
        if key in node:
            parts.append(f"{sign} {node[key]}")
    return ", ".join(parts)


def _resolve(node: dict, defs: dict) -> dict:
    """The node with its ``$ref`` replaced by the definition (the node's own keys win)."""
    while "$ref" in node:
        ref = defs[node["$ref"].rsplit("/", 1)[-1]]
        node = {**ref, **{k: v for k, v in node.items() if k != "$ref"}}
    return node


def _rows(node: dict, path: str, defs: dict, out: list) -> None:
    node = _resolve(node, defs)
    if path:
        default = node.get("default")
        out.append((path, _type(node, defs), _bounds(node),
                    "" if default is None else f"`{default!r}`" if not isinstance(
                        default, str) else f"`{default}`",
                    node.get("description", "")))
    for name, child in (node.get("properties") or {}).items():
        _rows(child, f"{path}.{name}" if path else name, defs, out)
    extra = node.get("additionalProperties")
    if isinstance(extra, dict):
        _rows(extra, f"{path}.<name>", defs, out)
    items = node.get("items")
    if isinstance(items, dict):
        items = _resolve(items, defs)
        if items.get("properties"):
            for name, child in items["properties"].items():
                _rows(child, f"{path}[].{name}", defs, out)


def config_markdown(schema: dict) -> str:
    """The workflow configuration's reference page: one row per property of the schema,
    nested properties by their dotted path (``<name>``: any key, ``[]``: each list item)."""
    rows: list = []
    _rows(schema, "", schema.get("$defs", {}), rows)
    lines = [
        "# Workflow configuration",
        "",
        "Generated from `workflow/schemas/config.schema.yaml`, against which the workflow "
        "checks `config/config.yaml` before any job runs. "
        + _cell(schema.get("description", "")),
        "",
        "Presets and how the studies use them: [Workflow and presets]"
        "(../explanation/workflow.md).",
        "",
        "| key | type | bounds | default | description |",
        "|---|---|---|---|---|",
    ]
    lines += [f"| `{p}` | {_cell(t)} | {_cell(b)} | {_cell(d)} | {_cell(desc)} |"
              for p, t, b, d, desc in rows]
    return "\n".join(lines) + "\n"


def write_pages(app=None) -> list[str]:
    """Write the generated reference pages; returns the pages written or kept."""
    done = []
    for page, (module, func, title, lead) in FROM_CODE.items():
        try:
            make = getattr(importlib.import_module(module), func)
        except (ImportError, AttributeError):
            continue
        text = make().strip()
        if not text.startswith("# "):       # a generator that gives no title gets ours
            text = f"# {title}\n\n{lead}\n\n{text}"
        _write(page, text + "\n")
        done.append(page)
    _write("reference/config.md",
           config_markdown(yaml.safe_load(SCHEMA.read_text(encoding="utf-8"))))
    done.append("reference/config.md")
    return done


def setup(app):
    app.connect("builder-inited", write_pages)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
