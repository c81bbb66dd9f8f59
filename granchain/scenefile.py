"""Reading a scene file: bytes -> UTF-8 text -> YAML mapping, and ``--set`` overrides.

Every problem is a one-line :class:`~granchain.errors.SceneError` naming the file or the
key: a path that is missing, a directory, not a regular file or larger than a scene can be;
text that is not UTF-8; YAML that does not parse, gives a key twice in one mapping, holds
more values than a scene can (YAML aliases expanded), nests too deep or writes a number
with too many digits (:class:`SceneLoader`). Each is found with work bounded by the file's
size, whatever its aliases stand for.
Validation of the mapping is ``granchain.scene``'s job (its checks: ``granchain.scenecheck``).
"""
from __future__ import annotations

import copy
import stat
from pathlib import Path

import yaml
from yaml.composer import Composer
from yaml.constructor import SafeConstructor
from yaml.events import AliasEvent, ScalarEvent
from yaml.nodes import ScalarNode
from yaml.resolver import Resolver

from .errors import SceneError

MAX_SCENE_BYTES = 1 << 20      # a scene is a page of YAML; anything larger is not a scene
# The most values (numbers, names, keys, list entries, and each mapping or list) a scene
# file may hold, counted with YAML aliases expanded: per-sphere lists (chain.radius,
# chain.materials, gaps.values) of up to ~50000 entries in all fit. Reading and validating
# the largest such file takes about a second (benchmarks/hostile_scenes.py); an alias
# "bomb" (a few hundred bytes standing for 10^9 values) is refused after this many.
MAX_VALUES = 50_000
# The deepest nesting of lists and mappings (a scene needs 4: chain.materials[i].E)
MAX_DEPTH = 10
# The longest number (characters) YAML may read: sexagesimal integers (1:00:00...) cost
# time quadratic in their length
MAX_NUMBER_CHARS = 1000

try:                        # libyaml's event parser (C), ~10x faster than the pure-Python one
    from yaml.cyaml import CParser as _CParser
    _PARSER: tuple = (_CParser,)
except ImportError:         # pragma: no cover - PyYAML without libyaml
    from yaml.parser import Parser
    from yaml.reader import Reader
    from yaml.scanner import Scanner
    _CParser = None
    _PARSER = (Reader, Scanner, Parser)

_NUMBER_TAGS = ("tag:yaml.org,2002:int", "tag:yaml.org,2002:float")


def key_of(path: str) -> str:
    """The key part of a value's path: 'chain.n[3][0]' -> 'chain.n' ('<file>' at the top)."""
    return path.partition("[")[0] or "<file>"


class SceneLoader(Composer, SafeConstructor, Resolver, *_PARSER):
    """YAML safe loader for scene files.

    It refuses, naming the key's path: a key given twice in one mapping (at any depth; the
    line of its second occurrence), more than MAX_VALUES values with YAML aliases expanded
    (counted while the document is composed, so a large file or an alias bomb stops
    early), an alias to the value that holds it, nesting deeper than MAX_DEPTH, and a
    number longer than MAX_NUMBER_CHARS characters. The events come from libyaml when
    PyYAML has it; the document is composed here, so its depth is checked before any
    recursion."""

    def __init__(self, stream, root: str = ""):
        if _CParser is not None:
            _CParser.__init__(self, stream)
        else:                                   # pragma: no cover
            Reader.__init__(self, stream)
            Scanner.__init__(self)
            Parser.__init__(self)
        Composer.__init__(self)
        SafeConstructor.__init__(self)
        Resolver.__init__(self)
        self._paths: dict[int, str] = {}
        self._root = root
        self._stack: list[str] = []       # paths of the collections being composed
        self._count = 0                   # values so far, aliases expanded
        self._sizes: dict[int, int] = {}  # anchored node -> its values, aliases expanded

    def _path_of(self, node) -> str:
        return self._paths.get(id(node), self._root)

    # --- composing: count, depth, aliases ----------------------------------------------
    def _child_path(self, index) -> str:
        base = self._stack[-1] if self._stack else self._root
        if isinstance(index, int) and not isinstance(index, bool):
            return f"{base}[{index}]"
        if index is None:                         # a mapping's key, or the document
            return base
        seg = index.value if isinstance(index, ScalarNode) else "?"
        return f"{base}.{seg}" if base else str(seg)

    def _add(self, values: int, index) -> None:
        self._count += values
        if self._count > MAX_VALUES:
            raise SceneError(key_of(self._child_path(index)), f"the scene file holds more "
                             f"than {MAX_VALUES} values up to here (numbers, names, keys and "
                             "list entries, YAML aliases expanded)", "a scene needs far fewer: "
                             "write the value out, one number or a list of at most one entry "
                             "per sphere")

    def compose_node(self, parent, index):
        event = self.peek_event()
        if isinstance(event, AliasEvent):
            node = self.anchors.get(event.anchor)
            if node is not None:
                size = self._sizes.get(id(node))
                if size is None:
                    raise SceneError(key_of(self._child_path(index)), "a YAML alias refers "
                                     "to the value that holds it (the value would contain "
                                     "itself)", "write the value out without that alias")
                self._add(size, index)
            return super().compose_node(parent, index)
        self._add(1, index)
        if isinstance(event, ScalarEvent):
            # the common case, composed without the base class's checks when unanchored
            node = (self.compose_scalar_node(None) if event.anchor is None
                    else super().compose_node(parent, index))
            if event.anchor is not None:
                self._sizes[id(node)] = 1
            if node.tag in _NUMBER_TAGS and len(node.value) > MAX_NUMBER_CHARS:
                raise SceneError(key_of(self._child_path(index)), f"a number written with "
                                 f"{len(node.value)} characters (at most "
                                 f"{MAX_NUMBER_CHARS})", "give the number in a few digits, "
                                 "e.g. 1.5e-4")
            return node
        if len(self._stack) >= MAX_DEPTH:
            raise SceneError(key_of(self._child_path(index)), f"lists and mappings nest "
                             f"deeper than {MAX_DEPTH} levels", "a scene value is a number, a "
                             "name, a list of them or a small mapping")
        start = self._count - 1
        self._stack.append(self._child_path(index))
        try:
            node = super().compose_node(parent, index)
        finally:
            self._stack.pop()
        if event.anchor is not None:
            self._sizes[id(node)] = self._count - start
        return node

    # --- constructing: duplicate keys ----------------------------------------------------
    def construct_mapping(self, node, deep=False):
        if isinstance(node, yaml.MappingNode):
            base = self._path_of(node)
            seen = set()
            for key_node, value_node in node.value:
                if key_node.tag == "tag:yaml.org,2002:merge":
                    continue
                key = self.construct_object(key_node, deep=True)
                try:
                    hash(key)
                except TypeError:
                    continue                     # the base class reports it
                where = f"{base}.{key}" if base else str(key)
                if key in seen:
                    raise SceneError(where, f"duplicate key (again at line "
                                            f"{key_node.start_mark.line + 1})",
                                     "keep one of the entries")
                seen.add(key)
                self._paths[id(value_node)] = where
        return super().construct_mapping(node, deep=deep)

    def construct_sequence(self, node, deep=False):
        if isinstance(node, yaml.SequenceNode):
            base = self._path_of(node)
            for i, child in enumerate(node.value):
                self._paths[id(child)] = f"{base}[{i}]"
        return super().construct_sequence(node, deep=deep)


SceneLoader.add_constructor("tag:yaml.org,2002:map", SceneLoader.construct_yaml_map)
SceneLoader.add_constructor("tag:yaml.org,2002:seq", SceneLoader.construct_yaml_seq)


def parse_yaml(text: str, what: str, root: str = ""):
    """A YAML document read with :class:`SceneLoader`; every failure is a SceneError.
    ``root``: the key path of the document (an override's key)."""
    loader = None
    try:
        loader = SceneLoader(text, root)      # its reader refuses non-printable characters
        return loader.get_single_data()
    except SceneError:
        raise
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark else ""
        position = getattr(exc, "position", None)          # a reader's error
        if not mark and isinstance(position, int):
            where = f" at line {text.count(chr(10), 0, position) + 1}"
        problem = (getattr(exc, "problem", None) or getattr(exc, "reason", None)
                   or "syntax error")
        raise SceneError("<file>", f"{what} is not valid YAML{where} ({problem})",
                         "fix the YAML syntax") from None
    except (ValueError, TypeError, OverflowError, RecursionError) as exc:
        # e.g. a date-like value that is no date (2024-13-45): the constructors raise these
        raise SceneError("<file>", f"{what} has a value YAML cannot read ({type(exc).__name__}: "
                         f"{str(exc)[:80]!r})", "quote the value or fix it") from None
    finally:
        if loader is not None:
            loader.dispose()


def read_scene_file(path: str | Path) -> dict:
    """The mapping of a scene file; a missing, unreadable, non-UTF-8 or non-YAML file is a
    one-line SceneError."""
    shown = repr(str(path))
    if str(path) == "":
        raise SceneError("<file>", "the scene path is empty", "give the path of a scene YAML file")
    path = Path(path)
    try:
        st = path.stat()
        if stat.S_ISDIR(st.st_mode):
            raise IsADirectoryError
        if not stat.S_ISREG(st.st_mode):
            raise SceneError("<file>", f"{shown} is not a regular file",
                             "give the path of a scene YAML file")
        if st.st_size > MAX_SCENE_BYTES:
            raise SceneError("<file>", f"{shown} has {st.st_size} bytes, more than a scene "
                             f"file can ({MAX_SCENE_BYTES})", "give the path of a scene YAML file")
        data = path.read_bytes()
    except FileNotFoundError:
        raise SceneError("<file>", f"{shown} does not exist",
                         "give the path of a scene YAML file") from None
    except IsADirectoryError:
        raise SceneError("<file>", f"{shown} is a directory",
                         "give the path of a scene YAML file") from None
    except PermissionError:
        raise SceneError("<file>", f"{shown} cannot be read (permission denied)",
                         "make it readable or copy it somewhere you can read") from None
    except (OSError, ValueError) as exc:
        raise SceneError("<file>", f"{shown} cannot be read "
                         f"({getattr(exc, 'strerror', None) or exc})",
                         "give the path of a readable scene YAML file") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data[:exc.start].count(b"\n") + 1
        raise SceneError("<file>", f"{shown} is not UTF-8 text (byte {exc.start}, line {line})",
                         "save the scene file as UTF-8") from None
    raw = parse_yaml(text, shown)
    if raw is None:
        raw = {}
    if not isinstance(raw, dict):
        raise SceneError("<file>", "the top level is not a mapping", "write 'key: value' lines")
    return raw


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
            value = parse_yaml(text, f"the value of --set {key.strip()}", key.strip())
        except SceneError as exc:
            if exc.field != "<file>":
                raise
            value = text
        node = raw
        for p in parts[:-1]:
            if not isinstance(node.get(p, {}), dict):
                node[p] = {}
            node = node.setdefault(p, {})
        node[parts[-1]] = value
    return raw
