"""Reading a scene file: bytes -> UTF-8 text -> YAML mapping, and ``--set`` overrides.

Every problem is a one-line :class:`~granchain.errors.SceneError` naming the file or the
key: a path that is missing, a directory, not a regular file or larger than a scene can be;
text that is not UTF-8; YAML that does not parse, or gives a key twice in one mapping.
Validation of the mapping is ``granchain.scene``'s job.
"""
from __future__ import annotations

import copy
import stat
from pathlib import Path

import yaml

from .errors import SceneError

MAX_SCENE_BYTES = 1 << 20      # a scene is a page of YAML; anything larger is not a scene


class SceneLoader(yaml.SafeLoader):
    """YAML SafeLoader that refuses a key given twice in one mapping (at any depth),
    naming the key's path and the line of its second occurrence."""

    def __init__(self, stream, root: str = ""):
        super().__init__(stream)
        self._paths: dict[int, str] = {}
        self._root = root

    def _path_of(self, node) -> str:
        return self._paths.get(id(node), self._root)

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
        problem = getattr(exc, "problem", None) or "syntax error"
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
