"""Hostile scenes: every refusal does bounded work and names the key at fault; no contact or
wall runs past the range of Hertz contact; no key is silently overridden by another.

Bounded work: a YAML alias "bomb" (a few hundred bytes standing for 10^9 values), deep
nesting, long numbers, huge keys, and the largest files and chains a scene may describe
are answered within 200 MB (measured in a subprocess whose address space is capped, so a
regression fails instead of exhausting the machine). Overlaps: the bound of
``guards.overlaps`` is checked against the independent solver (tests/independent.py) on
chains of unlike spheres, a heavy striker and a preloaded wall."""
from __future__ import annotations

import math
import os
import resource
import subprocess
import sys
import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from granchain import guards
from granchain.cli import main
from granchain.errors import SceneError
from granchain.scene import scene_from_dict
from granchain.validate import short

from conftest import REPO, write
from conftest import refused as refused_line
from independent import hertz_chain_general

SS440 = (200e9, 0.28, 7800.0)          # the library's ss440c, ptfe and tungsten carbide,
PTFE = (1.46e9, 0.46, 2200.0)          # written out (the independent solver shares no data)
WC = (620e9, 0.24, 14900.0)



def refused(capsys, argv, field: str) -> str:
    """The CLI refuses in one line naming the scene field ``field``."""
    return refused_line(capsys, argv, f"scene field '{field}'")


# ---------------------------------------------------------------------------------------
# refusals do bounded work
# ---------------------------------------------------------------------------------------
def _dag(levels: int, fan: int = 10):
    """A list standing for fan^levels leaves through shared sublists (what YAML aliases
    build), made with work proportional to levels."""
    node = [1] * fan
    for _ in range(levels - 1):
        node = [node] * fan
    return node


def test_short_summarises_any_value_with_bounded_work():
    tracemalloc.start()
    try:
        text = short(_dag(7))                       # 10^7 leaves: repr() would be ~40 MB
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 1e6, peak
    assert len(text) <= 90 and text.startswith("[[[") and "(10 entries)" in text
    assert "5001 digits" in short(10**5000)         # repr() refuses ints of > 4300 digits
    loop = [1]
    loop.append(loop)
    assert len(short(loop)) <= 90
    big = short("x" * 10**6)
    assert len(big) <= 90 and "1000000 characters" in big
    assert short({"E": 2e11, "nu": 0.3}) == "{'E': 200000000000.0, 'nu': 0.3}"


def test_a_refusal_cuts_a_key_of_any_length():
    err = SceneError("x" * 10**6, "unknown key", "did you mean 'name'?")
    assert len(str(err)) < 200 and str(err).endswith("unknown key; did you mean 'name'?")


ALIAS_BOMB = "chain:\n  n: [&a [1,1,1,1,1,1,1,1,1,1],\n" + "".join(
    f"      &{b} [{','.join(['*' + a] * 10)}]{']' if b == 'i' else ','}\n"
    for a, b in zip("abcdefgh", "bcdefghi"))                 # 10^9 leaves in ~400 bytes
MERGE_BOMB = "chain:\n  n: [&m0 {k: 1},\n" + "".join(
    f"      &m{i} {{<<: [*m{i - 1}, *m{i - 1}, *m{i - 1}]}}{']' if i == 30 else ','}\n"
    for i in range(1, 31))                                   # 3^30 merged keys

HOSTILE = {
    # name: (scene text, field named, words of the refusal)
    "alias bomb": (ALIAS_BOMB, "chain.n", "more than 50000 values"),
    "merge-key bomb": (MERGE_BOMB, "chain.n", "more than 50000 values"),
    "alias inside itself": ("chain:\n  radius: &r [1.0e-4, *r]\n", "chain.radius",
                            "contain itself"),
    "deep nesting": ("chain:\n  n: " + "[" * 100000 + "]" * 100000 + "\n", "chain.n",
                     "deeper than 10"),
    "sexagesimal integer": ("chain:\n  n: 1" + ":00" * 40000 + "\n", "chain.n",
                            "120001 characters"),
    "integer of 5000 digits": ("chain:\n  n: 1" + "0" * 5000 + "\n", "chain.n",
                               "5001 characters"),
    "list of 60000 entries": ("chain:\n  radius: [" + ",".join(["1"] * 60000) + "]\n",
                              "chain.radius", "more than 50000 values"),
    "key of 100000 characters": ("? " + "k" * 100000 + "\n: 1\n", "k" * 97 + "...",
                                 "unknown key"),
    "name of 1 MB": ("name: " + "n" * 1_000_000 + "\n", "name", "1000000 characters"),
}


@pytest.mark.parametrize("case", sorted(HOSTILE))
def test_hostile_scene_files_are_refused_in_one_short_line(tmp_path, capsys, case):
    text, field, words = HOSTILE[case]
    assert len(text.encode()) <= 1 << 20
    err = refused(capsys, ["validate", write(tmp_path, text)], field)
    assert words in err and len(err) < 1200, err


# the child's own peak resident memory (VmHWM, in kB): getrusage's ru_maxrss would carry
# the parent's size over fork and exec
PEAK_RSS = ("import sys\nfrom granchain.cli import main\nrc = main(sys.argv[1:])\n"
            "hwm = [ln for ln in open('/proc/self/status') if ln.startswith('VmHWM')]\n"
            "open(sys.argv.pop(), 'w').write(hwm[0].split()[1])\nsys.exit(rc)\n")


def _validate_in_subprocess(path: str, tmp_path: Path) -> tuple[int, str, float]:
    """(exit status, stderr, peak resident memory in MB) of ``granchain validate path`` in
    a child whose address space is capped at 2 GB (a regression fails, it cannot take the
    machine's memory); a child still running after 120 s fails the test."""
    rss = tmp_path / "rss"
    code = PEAK_RSS.replace("sys.argv.pop()", repr(str(rss)))

    def cap():
        resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30))
    p = subprocess.run([sys.executable, "-c", code, "validate", path], capture_output=True,
                       text=True, timeout=120, preexec_fn=cap, cwd=REPO,
                       env=dict(os.environ, PYTHONPATH=str(REPO)))
    return p.returncode, p.stderr, float(rss.read_text()) / 1024 if rss.exists() else math.inf


@pytest.mark.parametrize("text, field", [
    (ALIAS_BOMB, "chain.n"),
    ("chain: {n: 1000000, radius_spread: {sd: 1.0e-6}}\nwalls: {end: rigid}\n"
     "precompression: {force: 0.01}\n", None),
], ids=["alias bomb", "1e6 spheres"])
def test_a_bomb_and_the_largest_chain_are_answered_within_200_mb(tmp_path, text, field):
    """The 400-byte alias bomb under chain.n (10^9 values) is refused, and a chain of 10^6
    spheres with a wall, a preload and a radius spread (n-1 contacts to check) is
    validated, each by a process that never holds more than 200 MB."""
    rc, err, mb = _validate_in_subprocess(write(tmp_path, text), tmp_path)
    if field:
        assert rc == 2 and err.count("\n") == 1 and f"'{field}'" in err, err
    else:
        assert rc == 0, err
    assert mb < 200, mb


# ---------------------------------------------------------------------------------------
# every contact and the wall: static and peak overlaps
# ---------------------------------------------------------------------------------------
RIGID_PRELOAD = "walls: {{end: rigid}}\nprecompression: {{force: {F}}}\n"


@pytest.mark.parametrize("force", ["1.0e6", "1.0e3"])
def test_a_preload_past_hertz_is_refused_by_validate_and_run(tmp_path, capsys, force):
    """150 um 440C spheres on a rigid wall: 1e6 N presses each contact ~57 R deep at rest
    (it used to run and print v_g = 2.6e4 m/s), 1e3 N 0.57 R (a negative dt)."""
    scene = write(tmp_path, RIGID_PRELOAD.format(F=force))
    for cmd in ("validate", "run"):
        err = refused(capsys, [cmd, scene], "precompression.force")
        assert "R* deep at rest" in err


def test_the_largest_preload_shown_is_accepted(tmp_path, capsys):
    err = refused(capsys, ["validate", write(tmp_path, RIGID_PRELOAD.format(F=100))],
                  "precompression.force")
    limit = float(err.split("give precompression.force <= ")[1].split()[0])
    sc = scene_from_dict({"walls": {"end": "rigid"}, "precompression": {"force": limit}})
    worst = max(o.static_ratio for o in guards.overlaps(sc, 0.1))
    assert 0.9 * guards.HARD_OVERLAP_RATIO < worst <= guards.HARD_OVERLAP_RATIO
    # the pair contacts (R* = R/2) hold less than the rigid wall (R* = R, stiffer E*)
    R, E, nu = 150e-6, 200e9, 0.28
    K = 4 / 3 * E / (2 * (1 - nu**2)) * math.sqrt(R / 2)
    assert limit == pytest.approx(K * (0.1 * R / 2) ** 1.5, rel=0.05)


def test_a_striker_too_fast_for_hertz_is_refused_with_the_speed_that_is_not(tmp_path, capsys):
    err = refused(capsys, ["validate", write(tmp_path, "striker: {velocity: [0.1, 3000]}\n")],
                  "striker.velocity")
    limit = float(err.split("give striker speeds <= ")[1].split()[0])
    scene_from_dict({"striker": {"velocity": [0.1, limit]}})
    refused(capsys, ["validate", write(tmp_path, "striker: {velocity: 1.0e300}\n")],
            "striker.velocity")


def _max_overlaps(radii, mats, v, wall=None, preload=0.0, t_end=20e-6):
    """Each contact's (and the wall's, last) largest overlap over R*, from the independent
    solver's dense solution."""
    g = hertz_chain_general(radii, mats, v, t_end, wall=wall, preload=preload)
    n = len(radii)
    t = np.linspace(g.sol.t[0], g.sol.t[-1], 20000)
    u = g.sol.sol(t)[:n] * g.delta0
    out = [(g.delta_static[i] + u[i] - u[i + 1]).max()
           / (radii[i] * radii[i + 1] / (radii[i] + radii[i + 1])) for i in range(n - 1)]
    if wall is not None:
        out.append((g.delta_static_wall + u[-1]).max() / radii[-1])
    return np.array(out)


def _scene_material(m):
    return {"E": m[0], "nu": m[1], "rho": m[2]}


FIELD_CHAINS = {
    # name: (radii, materials, v_s, wall, preload)
    "ptfe third": ([150e-6] * 8, [SS440, SS440, PTFE] + [SS440] * 5, 0.5, None, 0.0),
    "heavy striker": ([300e-6] + [150e-6] * 7, [WC] + [SS440] * 7, 0.5, None, 0.0),
    "ptfe on a preloaded rigid wall": ([150e-6] * 8, [SS440] * 7 + [PTFE], 0.2, "rigid", 0.05),
}


@pytest.mark.parametrize("case", sorted(FIELD_CHAINS))
def test_the_overlap_bound_holds_at_every_contact_and_the_wall(case):
    """guards.overlaps bounds each contact's largest overlap (the striker's whole energy in
    that contact, on its static overlap) and is not loose by more than 2.5x where it
    matters, the most pressed contact."""
    radii, mats, v, wall, F0 = FIELD_CHAINS[case]
    raw = {"chain": {"n": len(radii), "radius": radii,
                     "materials": [_scene_material(m) for m in mats]},
           "striker": {"velocity": v}, "probes": [2, len(radii)]}
    if wall:
        raw.update(walls={"end": wall}, precompression={"force": F0})
    sc = scene_from_dict(raw)
    bound = np.array([o.peak_ratio for o in guards.overlaps(sc, v)])
    sim = _max_overlaps(radii, mats, v, wall, F0, 30e-6 if wall else 20e-6)
    assert (sim <= bound * (1 + 1e-9)).all(), (sim, bound)
    assert sim.max() > bound.max() / 2.5, (sim, bound)


def test_a_soft_sphere_down_the_chain_warns_where_it_overlaps(tmp_path, capsys):
    """The PTFE sphere third in a 440C chain overlaps its neighbours by more than 1 % of R*
    at 0.5 m/s (the striker's own contact by 0.25 %): validate names that contact."""
    radii, mats, v, _, _ = FIELD_CHAINS["ptfe third"]
    assert _max_overlaps(radii, mats, v)[1:3].max() > guards.MAX_OVERLAP_RATIO
    scene = write(tmp_path, "chain: {n: 8, materials: [ss440c, ss440c, ptfe, ss440c, ss440c, "
                  "ss440c, ss440c, ss440c]}\nstriker: {velocity: 0.5}\nprobes: [2, 8]\n")
    assert main(["validate", scene]) == 0
    warn = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("warning:")]
    assert len(warn) == 1 and "contact 2-3 (ss440c-ptfe)" in warn[0], warn


def test_the_wall_contact_is_checked_with_its_own_material(tmp_path, capsys):
    """A soft wall: the chain's contacts are fine, the last sphere on the wall is not."""
    err = refused(capsys, ["validate", write(tmp_path, "walls: {end: {E: 1.0e4, nu: 0.3}}\n")],
                  "striker.velocity")
    assert "sphere 15 on the wall (ss440c on custom)" in err
    assert main(["validate", write(tmp_path, "walls: {end: {E: 1.0e7, nu: 0.3}}\n")]) == 0
    warn = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("warning:")]
    assert len(warn) == 1 and "sphere 15 on the wall" in warn[0], warn


# ---------------------------------------------------------------------------------------
# no key silently overridden
# ---------------------------------------------------------------------------------------
LIST15 = "[" + ", ".join(["ss440c"] * 15) + "]"
RADII15 = "[" + ", ".join(["150.0e-6"] * 15) + "]"


CONFLICTS = [
    (f"material: brass\nchain: {{materials: {LIST15}}}\n", "material",
     "beside the chain.materials list"),
    (f"chain: {{radius: {RADII15}}}\nstriker: {{radius: 189.0e-6}}\n", "striker.radius",
     "chain.radius[0]"),
    (f"chain: {{materials: {LIST15}}}\nstriker: {{material: brass}}\n", "striker.material",
     "chain.materials[0]"),
    ("walls: {end: {E: 200.0e9, nu: 0.28, rho: 7800}}\n", "walls.end.rho", "does not move"),
    ("chain: {materials: brass}\n", "chain.materials", "write material: brass"),
]


@pytest.mark.parametrize("text, field, words", CONFLICTS, ids=[c[1] for c in CONFLICTS])
def test_a_key_another_key_overrides_is_refused(tmp_path, capsys, text, field, words):
    err = refused(capsys, ["validate", write(tmp_path, text)], field)
    assert words in err, err


def test_each_sphere_takes_its_own_key_without_a_conflict():
    sc = scene_from_dict({"material": "brass", "striker": {"material": "ss440c",
                                                           "radius": 189e-6}})
    assert sc.materials[0].name == "ss440c" and {m.name for m in sc.materials[1:]} == {"brass"}
    assert sc.radii[0] == 189e-6 and set(sc.radii[1:]) == {150e-6}


# ---------------------------------------------------------------------------------------
# the key at fault is named
# ---------------------------------------------------------------------------------------
AT_FAULT = [
    ("material: {E: 200.0e9, nu: 0.28, rho: 1.0e308}\n", "material.rho"),
    ("chain: {materials: [ss440c, ss440c, ss440c, {E: 1.0e300, nu: 0.3, rho: 7800}, ss440c,"
     " ss440c, ss440c, ss440c, ss440c, ss440c, ss440c, ss440c, ss440c, ss440c, ss440c]}\n",
     "chain.materials[3].E"),
    ("striker: {material: {E: 200.0e9, nu: 0.5, rho: 7800}}\n", "striker.material.nu"),
    ("walls: {end: {E: 1.0e-300, nu: 0.3}}\n", "walls.end.E"),
    ("effects: [hertz, contact_damping]\ndamping: {model: viscoelastic, eta: 1.0e20}\n"
     "integrator: {method: adaptive}\n", "damping.eta"),
    ("effects: [hertz, air_drag]\ndrag: {T0: 1.0e-300}\n", "drag.T0"),
    ("effects: [hertz, air_drag]\ndrag: {L: 1.0e-300}\n", "drag.L"),
    ("effects: [hertz, groove_friction]\ngroove: {g: 1.0e300}\n", "groove.g"),
    ("striker: {radius: 1.0e-200}\n", "striker.radius"),
    ("chain: {radius: 1.0e100}\n", "chain.radius"),
]


@pytest.mark.parametrize("text, field", AT_FAULT, ids=[c[1] for c in AT_FAULT])
def test_the_key_at_fault_is_named_before_any_run(tmp_path, capsys, text, field):
    """Each of these used to run (to non-finite numbers) or blame another key."""
    refused(capsys, ["validate", write(tmp_path, text)], field)


def test_damping_eta_up_to_the_limit_shown_is_accepted(tmp_path, capsys):
    text = ("effects: [hertz, contact_damping]\ndamping: {{model: viscoelastic, eta: {eta}}}\n"
            "integrator: {{method: adaptive}}\n")
    err = refused(capsys, ["validate", write(tmp_path, text.format(eta="1.0e20"))],
                  "damping.eta")
    limit = err.split("give eta <= ")[1].strip()
    assert main(["validate", write(tmp_path, text.format(eta=limit))]) == 0
