"""Writing result files safely: one helper for every file granchain writes.

``check_output_path(path, force, field, kind=...)`` refuses, with one line naming
``field`` (an option such as ``--out``), a target that cannot or must not be written: its
directory is missing or not writable, it is a directory or not a regular file, it exists
and ``force`` is not given, or it exists and is not an earlier output of the same
``kind`` (an :class:`OutputKind`: ``--force`` replaces an earlier result, never a
measurement, a scene or another command's file). ``check_distinct(outputs, inputs)``
refuses an output that is one of the command's inputs or another of its outputs, with or
without ``force``: paths are compared as files (``same_file``: real paths with symlinks
resolved, and the same inode for hard links). Callers run both before any computation.

``atomic_write_text`` / ``atomic_write_bytes`` write into a new temporary file created
with ``tempfile.mkstemp`` in the target's directory (``.NAME.XXXXXXXX.tmp``: created
exclusively, so it never follows a symlink nor replaces an existing file), fsync it and
then move it onto the target: with ``force`` by ``os.replace``; without, by a hard link
that fails if anything (a file, a symlink) appeared under the target's name meanwhile, so
nothing is ever overwritten unasked. On any failure the temporary file is removed and the
target is left as it was.

``json_text(obj, indent)`` is ``json.dumps(jsonable(obj), indent=indent)``, byte for byte
(non-finite floats written as null), built with the C string encoder and ``float.__repr__``
on whole lists of scalars at once instead of the standard library's pure-Python indenting
encoder.
"""
from __future__ import annotations

import errno
import json
import math
import os
import stat
import tempfile
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Callable

from .errors import GranchainError

__all__ = ["check_output_path", "check_distinct", "same_file", "OutputKind", "json_output",
           "IMAGE", "file_head", "atomic_write_text", "atomic_write_bytes", "jsonable", "json_text"]


def _show(path) -> str:
    """A path for a one-line message (control characters escaped)."""
    return repr(str(path))


def _fail(field: str, problem: str, fix: str) -> GranchainError:
    return GranchainError(f"{field}: {problem}; {fix}")


@dataclass(frozen=True)
class OutputKind:
    """What an output file is, for ``--force``: ``what`` names it in messages ("a granchain
    run JSON document"), ``looks_like(path)`` tells whether an existing file is one (it
    reads at most the file's head, or parses a JSON document)."""
    what: str
    looks_like: Callable[[Path], bool]


def file_head(path: Path, size: int = 4096) -> bytes:
    """The first ``size`` bytes of a file (empty if it cannot be read)."""
    try:
        with open(path, "rb") as f:
            return f.read(size)
    except OSError:
        return b""


def json_output(what: str, *keysets) -> OutputKind:
    """A JSON object holding every key of one of ``keysets``: the documents granchain's
    commands write (the file is parsed whole; anything else is not one)."""
    def looks_like(path: Path) -> bool:
        if not file_head(path, 64).lstrip().startswith(b"{"):
            return False
        try:
            doc = json.loads(Path(path).read_bytes())
        except (OSError, ValueError, RecursionError):
            return False
        return isinstance(doc, dict) and any(set(k) <= doc.keys() for k in keysets)
    return OutputKind(what, looks_like)


# the first bytes of each image format a figure is written in, by suffix
_MAGIC = {".png": (b"\x89PNG\r\n\x1a\n",), ".pdf": (b"%PDF-",), ".svg": (b"<?xml", b"<svg")}
IMAGE = OutputKind("an image of its suffix's format (.png, .pdf or .svg)",
                   lambda p: file_head(p, 16).lstrip().startswith(
                       _MAGIC.get(Path(p).suffix.lower(), (b"\0\0no-such-magic",))))


def same_file(a, b) -> bool:
    """Do paths ``a`` and ``b`` name one file: equal real paths (every symlink resolved,
    the file need not exist) or, for two existing files, the same inode (hard links)?"""
    try:
        if os.path.realpath(a) == os.path.realpath(b):
            return True
        return os.path.exists(a) and os.path.exists(b) and os.path.samefile(a, b)
    except (OSError, ValueError):
        return False


def check_distinct(outputs, inputs=()) -> None:
    """Refuse (one line naming both) an output that is one of the inputs or another
    output, whether or not ``--force`` is given (module doc). ``outputs``, ``inputs``:
    (what, path) pairs, ``what`` an option or a description ("--out", "the scene file",
    "the --workdir file log.lammps"; an output's is the option that names it); a None
    path is skipped."""
    outputs = [(w, p) for w, p in outputs if p is not None and os.fspath(p) != ""]
    inputs = [(w, p) for w, p in inputs if p is not None and os.fspath(p) != ""]
    for i, (field, p) in enumerate(outputs):
        for what, q in inputs:
            if same_file(p, q):
                raise _fail(field, f"{_show(p)} is {what} ({_show(q)}): an output never "
                            "replaces an input, even with --force", "choose another path")
        for what, q in outputs[:i]:
            if same_file(p, q):
                raise _fail(field, f"{_show(p)} is also the output of {what}",
                            "give each output its own path")


def check_output_path(path, force: bool = False, field: str = "--out", *,
                      probe: bool = True, kind: OutputKind | None = None,
                      inside: bool = False) -> Path:
    """Refuse a target file that cannot or must not be written (see the module doc).

    ``probe``: also create and remove a temporary file in the directory, which proves it
    writable where permission bits do not tell (root, read-only file systems). ``kind``:
    with ``force``, an existing target must be an earlier output of this kind. ``inside``:
    the file's name is granchain's, in a directory the user gave as ``field`` (a working
    directory, a deck's directory), so a fix names that directory, not the file."""
    text = os.fspath(path)
    if not text or "\0" in text:
        raise _fail(field, f"{_show(text)} is not a file path", "give the path of a new file")
    path = Path(text)
    parent = path.parent
    if not parent.exists():
        raise _fail(field, f"directory {_show(parent)} does not exist",
                    "create it first or choose another path")
    if not parent.is_dir():
        raise _fail(field, f"{_show(parent)} is not a directory", "choose another path")
    if path.is_dir():
        if inside:
            raise _fail(field, f"{_show(path)} is a directory where this command writes its "
                        f"file {path.name}", "move that directory away or choose another "
                        "directory")
        raise _fail(field, f"{_show(path)} is a directory", "give the path of a file inside it")
    if os.path.lexists(path):
        if not force:
            raise _fail(field, f"{_show(path)} exists",
                        "choose another path or pass --force to replace it")
        st = os.lstat(path)
        if not (stat.S_ISREG(st.st_mode) or stat.S_ISLNK(st.st_mode)):
            raise _fail(field, f"{_show(path)} is not a regular file", "choose another path")
        if kind is not None and not kind.looks_like(path):
            raise _fail(field, f"{_show(path)} exists and is not {kind.what}: --force replaces "
                        "only an earlier output of the same kind",
                        "choose another path (or move that file away yourself)")
    if probe:
        try:
            fd, tmp = tempfile.mkstemp(dir=parent, prefix="." + path.name + ".", suffix=".tmp")
        except OSError as exc:
            raise _fail(field, f"cannot write into {_show(parent)} ({exc.strerror or exc})",
                        "choose a writable directory") from None
        os.close(fd)
        os.unlink(tmp)
    return path


def atomic_write_bytes(path, data: bytes, force: bool = False, field: str = "--out") -> Path:
    """Write ``data`` to ``path`` atomically (see the module doc); return the path."""
    path = check_output_path(path, force, field, probe=False)
    try:
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix="." + path.name + ".", suffix=".tmp")
    except OSError as exc:
        raise _fail(field, f"cannot write into {_show(path.parent)} ({exc.strerror or exc})",
                    "choose a writable directory") from None
    try:
        os.fchmod(fd, _file_mode())          # mkstemp makes 0600: use the usual umask mode
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        if force:
            os.replace(tmp, path)
        else:
            _move_no_clobber(tmp, path, field)
    except BaseException as exc:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        if isinstance(exc, OSError):
            raise _fail(field, f"cannot write {_show(path)} ({exc.strerror or exc})",
                        "check the disk and the permissions, or choose another path") from None
        raise
    return path


def _file_mode() -> int:
    """0666 less the process umask: the mode open() would have given a new file."""
    global _MODE
    if _MODE is None:
        mask = os.umask(0o022)
        os.umask(mask)
        _MODE = 0o666 & ~mask
    return _MODE


_MODE: int | None = None


def atomic_write_text(path, text: str, force: bool = False, field: str = "--out") -> Path:
    """``atomic_write_bytes`` of ``text`` in UTF-8."""
    return atomic_write_bytes(path, text.encode("utf-8"), force, field)


def _move_no_clobber(tmp: str, path: Path, field: str) -> None:
    try:
        os.link(tmp, path)
    except FileExistsError:
        raise _fail(field, f"{_show(path)} exists",
                    "choose another path or pass --force to replace it") from None
    except OSError as exc:
        if exc.errno not in (errno.EPERM, errno.EOPNOTSUPP, errno.ENOTSUP, errno.EXDEV, errno.EMLINK):
            raise
        # no hard links on this file system: check, then rename (a small race window)
        if os.path.lexists(path):
            raise _fail(field, f"{_show(path)} exists",
                        "choose another path or pass --force to replace it") from None
        os.replace(tmp, path)
        return
    os.unlink(tmp)


def cache_dir() -> Path:
    """Where granchain keeps what it can recompute (compiled kernels, simulated grids):
    ``$GRANCHAIN_CACHE_DIR``, else ``$XDG_CACHE_HOME/granchain``, else ``~/.cache/granchain``."""
    env = os.environ.get("GRANCHAIN_CACHE_DIR")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "granchain"


@lru_cache(maxsize=None)
def source_hash(*parts: str) -> str:
    """sha256 (hex) of the package's Python sources under ``parts`` (paths relative to the
    package; the whole package if none): a cache keyed by it is never reused after the code
    it was computed by has changed."""
    import hashlib
    pkg = Path(__file__).resolve().parent
    h = hashlib.sha256()
    for rel in parts or (".",):
        p = pkg / rel
        files = sorted(p.rglob("*.py")) if p.is_dir() else [p]
        for f in files:
            if "__pycache__" in f.parts:
                continue
            h.update(str(f.relative_to(pkg)).encode())
            h.update(f.read_bytes())
    return h.hexdigest()


def jsonable(obj):
    """``obj`` with every non-finite float (NaN, inf) replaced by None, dicts and lists
    (tuples as lists) copied through."""
    if isinstance(obj, float):
        return None if not math.isfinite(obj) else obj
    if isinstance(obj, dict):
        return {k: jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    return obj


_str = json.encoder.encode_basestring_ascii


def _float(x: float) -> str:
    return float.__repr__(x) if math.isfinite(x) else "null"


# exact types of the scalars a list is written from in one pass (subclasses of these, e.g.
# numpy's float64, take the general path, which treats them as json does)
_SCALARS = {float: _float, int: int.__repr__, str: _str, bool: lambda x: "true" if x else "false",
            type(None): lambda x: "null"}


_FLOAT = {float}
_NONFINITE = {float.__repr__(x) for x in (math.nan, math.inf, -math.inf)}


def json_text(obj, indent: int | None = None) -> str:
    """``json.dumps(jsonable(obj), indent=indent)``: the same text (see the module doc)."""
    out: list[str] = []
    _emit(obj, 0, indent, out)
    return "".join(out)


def _emit(o, depth: int, indent: int | None, out: list) -> None:
    if isinstance(o, str):
        out.append(_str(o))
    elif o is None:
        out.append("null")
    elif o is True:
        out.append("true")
    elif o is False:
        out.append("false")
    elif isinstance(o, int):
        out.append(int.__repr__(o))
    elif isinstance(o, float):
        out.append(_float(o))
    elif isinstance(o, dict) and all(type(k) is str for k in o):
        if not o:
            out.append("{}")
            return
        sep, between, end = _separators(depth, indent)
        lead = "{" + sep
        for k, v in o.items():
            scalar = _SCALARS.get(type(v))
            if scalar is not None:
                out.append(lead + _str(k) + ": " + scalar(v))
            else:
                out.append(lead + _str(k) + ": ")
                _emit(v, depth + 1, indent, out)
            lead = between
        out.append(end + "}")
    elif isinstance(o, (list, tuple)):
        if not o:
            out.append("[]")
            return
        sep, between, end = _separators(depth, indent)
        types = set(map(type, o))
        items = None
        if types == _FLOAT:
            items = list(map(float.__repr__, o))
            if not _NONFINITE.isdisjoint(items):
                items = ["null" if x in _NONFINITE else x for x in items]
        elif types <= _SCALARS.keys():
            items = [_SCALARS[type(x)](x) for x in o]
        if items is not None:
            out.append("[" + sep + between.join(items) + end + "]")
            return
        lead = "[" + sep
        for v in o:
            out.append(lead)
            lead = between
            _emit(v, depth + 1, indent, out)
        out.append(end + "]")
    else:
        # anything else (non-string keys, other types, errors): the standard library's
        # text, indented to this depth (a JSON text has no raw newline inside a string)
        text = json.dumps(jsonable(o), indent=indent)
        out.append(text if indent is None else text.replace("\n", "\n" + " " * (depth * indent)))


def _separators(depth: int, indent: int | None) -> tuple[str, str, str]:
    """(after the opening bracket, between two items, before the closing bracket) of a
    container at ``depth``: json.dumps's layout."""
    if indent is None:
        return "", ", ", ""
    inner = "\n" + " " * ((depth + 1) * indent)
    return inner, "," + inner, "\n" + " " * (depth * indent)
