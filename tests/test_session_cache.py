"""The test session's one cache directory: conftest.py points GRANCHAIN_CACHE_DIR at a
fresh temporary folder before anything is built, and every cache of the package (the
kernels' ahead-of-time module, the LAMMPS plugin) lives under that one variable."""
import os
import tempfile
from pathlib import Path

from granchain import fileio
from granchain.lammps import plugin


def test_session_cache_is_a_fresh_temporary_folder(session_cache_dir):
    assert os.environ["GRANCHAIN_CACHE_DIR"] == str(session_cache_dir)
    assert session_cache_dir.is_dir()
    assert session_cache_dir.name.startswith("granchain-test-cache-")
    assert session_cache_dir.parent == Path(tempfile.gettempdir())
    home_cache = Path.home() / ".cache"
    assert home_cache not in session_cache_dir.resolve().parents


def test_plugin_and_kernels_share_granchain_cache_dir(tmp_path, monkeypatch, session_cache_dir):
    assert plugin.cache_dir() == fileio.cache_dir() == session_cache_dir
    monkeypatch.setenv("GRANCHAIN_CACHE_DIR", str(tmp_path))
    monkeypatch.setenv("GRANCHAIN_CACHE", str(tmp_path / "not-this-one"))
    assert plugin.cache_dir() == fileio.cache_dir() == tmp_path
