"""The package's imports point one way: no import cycle anywhere, lazy imports (inside
functions) included, and the data layer loads no engine; and no module of the package is
longer than a reader can walk (:data:`MAX_MODULE_LINES`)."""
from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

PKG = Path(__file__).resolve().parents[1] / "granchain"
# the longest a module of the package may be, in lines (a longer one mixes jobs: split it)
MAX_MODULE_LINES = 650


def _module_name(path: Path) -> str:
    parts = path.relative_to(PKG.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in PKG.rglob("*.py")}


def _ancestors(name: str) -> list[str]:
    parts = name.split(".")
    return [".".join(parts[:i]) for i in range(1, len(parts))]


def import_graph() -> dict[str, set[str]]:
    """granchain module -> the granchain modules it imports, at any depth of its code.
    Importing a.b.c also runs the packages a.b and a (unless the importer lives in them)."""
    mods = _modules()
    graph: dict[str, set[str]] = {}
    for name, path in mods.items():
        is_pkg = path.name == "__init__.py"
        base = name if is_pkg else name.rpartition(".")[0]
        targets: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                targets.update(a.name for a in node.names)
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    anchor = base.split(".")
                    anchor = anchor[:len(anchor) - (node.level - 1)]
                    src = ".".join(anchor + ([node.module] if node.module else []))
                else:
                    src = node.module or ""
                targets.add(src)
                targets.update(f"{src}.{a.name}" for a in node.names)   # submodules
        own = set(_ancestors(name)) | {name}
        edges = set()
        for t in targets:
            for m in [t] + _ancestors(t):
                if m in mods and m not in own:
                    edges.add(m)
        graph[name] = edges
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(n: str) -> list[str] | None:
        state[n] = 1
        stack.append(n)
        for m in sorted(graph.get(n, ())):
            if state.get(m) == 1:
                return stack[stack.index(m):] + [m]
            if m not in state:
                found = visit(m)
                if found:
                    return found
        stack.pop()
        state[n] = 2
        return None

    for n in sorted(graph):
        if n not in state:
            found = visit(n)
            if found:
                return found
    return None


def long_modules(root: Path = PKG, limit: int = MAX_MODULE_LINES) -> dict[str, int]:
    """The Python modules below root longer than limit lines, with their lengths."""
    out = {}
    for p in sorted(root.rglob("*.py")):
        n = len(p.read_text().splitlines())
        if n > limit:
            out[str(p.relative_to(root.parent))] = n
    return out


def test_no_module_is_over_the_line_limit():
    assert long_modules() == {}


def test_the_line_limit_finds_a_long_module(tmp_path):
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "short.py").write_text("x = 1\n" * MAX_MODULE_LINES)
    (pkg / "sub" / "long.py").write_text("x = 1\n" * (MAX_MODULE_LINES + 1))
    assert long_modules(pkg) == {"pkg/sub/long.py": MAX_MODULE_LINES + 1}


def test_no_import_cycle_in_the_package():
    cycle = find_cycle(import_graph())
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


def test_the_cycle_finder_finds_a_lazy_cycle(tmp_path):
    """The walker sees imports inside functions, so a lazy cycle cannot hide."""
    graph = {"granchain.a": {"granchain.b"}, "granchain.b": {"granchain.c"},
             "granchain.c": {"granchain.a"}}
    assert find_cycle(graph) == ["granchain.a", "granchain.b", "granchain.c", "granchain.a"]
    src = "def f():\n    from granchain.simulate import run_scene\n"
    tree = ast.parse(src)
    lazy = [n for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)]
    assert lazy and lazy[0].module == "granchain.simulate"


# Layers, lowest first: a module may import its own layer and the layers before it. The
# effects (each one's law, parameters and scene section) sit below the scene, which
# validates each effect's section with the effect's own code.
LAYERS = (
    ("base", ("granchain", "granchain.errors", "granchain.materials", "granchain.fileio",
              "granchain.analytic", "granchain.scenefile", "granchain.validate",
              "granchain.units")),
    ("physics", ("granchain.effects",)),
    ("data", ("granchain.scene", "granchain.scenekeys", "granchain.scenecheck", "granchain.gaps",
              "granchain.guards", "granchain.gapdesign")),
    ("run plan", ("granchain.stoprule", "granchain.obsrules", "granchain.costmodel",
                  "granchain.runplan")),
    ("engines", ("granchain.trajectory", "granchain.engines", "granchain.lammps")),
    ("analysis", ("granchain.observables", "granchain.collision", "granchain.vibrometer",
                  "granchain.tables",
                  "granchain.columns",
                  "granchain.reductions", "granchain.modelcheck")),
    ("application", ("granchain.simulate",
                     "granchain.compare", "granchain.accuracy", "granchain.figures",
                     "granchain.thesis", "granchain.inference", "granchain.workflow",
                     "granchain.commands", "granchain.cli")),
)


def layer_of(module: str) -> int:
    """Index in LAYERS of the longest prefix naming the module."""
    best, depth = None, -1
    for k, (_, prefixes) in enumerate(LAYERS):
        for p in prefixes:
            if (module == p or module.startswith(p + ".")) and p.count(".") > depth:
                best, depth = k, p.count(".")
    assert best is not None, f"{module} is in no layer of tests/test_architecture.py"
    return best


def test_imports_point_down_the_layers():
    graph = import_graph()
    up = [f"{m} ({LAYERS[layer_of(m)][0]}) imports {t} ({LAYERS[layer_of(t)][0]})"
          for m in sorted(graph) for t in sorted(graph[m]) if layer_of(t) > layer_of(m)]
    assert not up, "\n".join(up)


def test_scene_layer_loads_no_engine():
    code = ("import sys, granchain.scene, granchain.gaps, granchain.guards; "
            "print(sorted(m for m in ('numba', 'scipy', 'lammps', 'MDAnalysis', 'matplotlib') "
            "if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "[]", out
