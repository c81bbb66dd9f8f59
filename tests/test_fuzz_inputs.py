"""Fuzzing the inputs a user writes: scene files (through the loader, the validator and the
CLI's ``validate``) and measurement CSVs for ``infer`` (``inference.read_measurements``).

The strategies build scenes near the valid ones and far from them: the field chains' keys
(radius and material lists, striker, walls, precompression, damping), numbers across 600
decades, wrong types, nesting, unknown keys, YAML aliases. Whatever they build, the answer
is a run-or-refuse decision: a valid scene, or one GranchainError whose message is one line
naming the key (``scene field '...'``) or the file, column and row. Never a traceback.

Each example's time is recorded (``-s`` prints the totals); ``benchmarks/hostile_scenes.py``
prints the distribution beside the time of a plain scene (no timed asserts here). The fast
tier runs FAST_SCENES scene files, FAST_SCENES scene mappings and FAST_CSVS measurement
files; the slow tier (``-m slow``) SLOW_SCENES, SLOW_SCENES and SLOW_CSVS.
"""
from __future__ import annotations

import contextlib
import io
import math
import re
import sys
import time

import pytest
import yaml
from hypothesis import HealthCheck, given, settings, strategies as st

from granchain.cli import main
from granchain.errors import GranchainError, SceneError
from granchain.inference import COLUMNS, read_measurements
from granchain.materials import library
from granchain.scene import scene_from_dict
from granchain.scenefile import parse_yaml

FAST_SCENES, SLOW_SCENES = 60, 3000
FAST_CSVS, SLOW_CSVS = 150, 3000
# seconds of each example, for the report (tests/test_fuzz_inputs.py -s prints them)
TIMES: dict[str, list[float]] = {"scene": [], "csv": []}

NAMES = sorted(library())
# a refusal: one line naming the key, the problem and the fix
# the field between quotes, a quote or backslash in a key the user wrote shown escaped
REFUSAL = re.compile(r"^granchain: error: scene field '(?:[^'\\]|\\.)+': [^\n]+; [^\n]+\n$")


# --- numbers across their range, and values of the wrong kind ---------------------------
def logs(lo: float, hi: float):
    """Positive floats log-uniform from lo to hi."""
    return st.floats(math.log10(lo), math.log10(hi)).map(lambda e: float(f"{10.0 ** e:.4g}"))


wild_numbers = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**30, 10**30),
    # integers of 5001 digits (beyond what repr() shows) and -1201 digits
    st.booleans().map(lambda big: 10**5000 if big else -10**1200),
    logs(1e-300, 1e300), logs(1e-300, 1e300).map(lambda x: -x), st.just(0), st.just(-0.0))
junk = st.recursive(
    st.one_of(st.none(), st.booleans(), wild_numbers, st.text(max_size=8),
              st.sampled_from(["auto", "rigid", "ss440c", "mindlin", "1e-9", "~", ".inf"])),
    lambda c: st.lists(c, max_size=4) | st.dictionaries(st.text(max_size=5), c, max_size=3),
    max_leaves=8)


# --- scenes ---------------------------------------------------------------------------
def material_maps(E, nu, rho):
    return st.fixed_dictionaries({"E": E, "nu": nu, "rho": rho},
                                 optional={"name": st.sampled_from(["m1", "bad name", "x" * 70])})


@st.composite
def scenes(draw) -> dict:
    """A scene mapping: half of them built from valid values only (lengths that fit, values
    in their physical ranges; they may still combine into a refusal: a preload without a
    wall, a striker too fast for its spheres), the others with wrong lengths and values of
    any kind, range and nesting anywhere."""
    clean = draw(st.booleans())

    def pick(good, bad=None):
        return draw(good if clean else st.one_of(good, bad if bad is not None else junk))

    materials = st.one_of(st.sampled_from(NAMES), material_maps(
        logs(1e8, 1e12), st.floats(-0.5, 0.49), logs(1e3, 2e4)))
    wild_materials = st.one_of(st.sampled_from(NAMES + ["steel", ""]), material_maps(
        st.one_of(logs(1e2, 1e14), junk), st.floats(-1.2, 0.7), logs(0.1, 1e6)))
    n = pick(st.integers(3, 12), st.sampled_from([1, 2, 10**7]))
    size = n if isinstance(n, int) and 0 < n <= 12 else 5
    length = size if clean else draw(st.sampled_from([size, size - 1, size + 1]))
    raw: dict = {"chain": {"n": n}}
    if draw(st.booleans()):
        raw["chain"]["radius"] = pick(
            st.one_of(logs(1e-5, 1e-2), st.lists(logs(1e-5, 1e-3), min_size=length,
                                                 max_size=length)),
            st.one_of(logs(1e-300, 1e300), junk))
    mats = None
    if draw(st.integers(0, 2)) == 0:
        mats = raw["chain"]["materials"] = pick(
            st.lists(materials, min_size=length, max_size=length),
            st.one_of(st.lists(wild_materials, min_size=length, max_size=length),
                      wild_materials))
    if mats is None or not clean:
        if draw(st.booleans()):
            raw["material"] = pick(materials, wild_materials)
    striker = {}
    if draw(st.booleans()):
        striker["velocity"] = pick(st.one_of(logs(1e-3, 5.0), st.lists(
            logs(1e-3, 5.0), min_size=1, max_size=3)), logs(1e-4, 1e300))
    if draw(st.integers(0, 4)) == 0 and not (clean and isinstance(
            raw["chain"].get("radius"), list)):
        striker["radius"] = pick(logs(1e-5, 1e-3))
    if draw(st.integers(0, 4)) == 0 and not (clean and mats is not None):
        striker["material"] = pick(materials, wild_materials)
    if striker:
        raw["striker"] = striker
    wall = draw(st.integers(0, 2)) == 0
    if wall:
        raw["walls"] = {"end": pick(st.one_of(
            st.sampled_from(NAMES + ["rigid"]),
            st.fixed_dictionaries({"E": logs(1e8, 1e12), "nu": st.floats(-0.5, 0.49)})))}
    if draw(st.integers(0, 2)) == 0 and (wall or not clean):
        raw["precompression"] = {"force": pick(logs(1e-6, 1.0), logs(1e-6, 1e300))}
    effects = ["hertz"] + draw(st.lists(st.sampled_from(
        ["rotation", "groove_friction", "air_drag", "contact_damping"]), unique=True,
        max_size=3))
    if draw(st.booleans()):
        raw["effects"] = pick(st.just(effects))
    if "contact_damping" in effects:
        raw["damping"] = pick(
            st.one_of(st.fixed_dictionaries({"e": st.floats(0.05, 1.0)}),
                      st.fixed_dictionaries({"model": st.just("viscoelastic"),
                                             "eta": logs(1e-3, 1e12)})),
            st.fixed_dictionaries({"model": st.sampled_from(["viscoelastic", "tsuji", "x"]),
                                   "e": st.one_of(logs(1e-300, 2.0), junk),
                                   "eta": logs(1e-3, 1e25), "limit_damping": junk}))
    if draw(st.integers(0, 3)) == 0 and "precompression" not in raw:
        raw["gaps"] = pick(st.one_of(
            st.fixed_dictionaries({"distribution": st.sampled_from(["fixed", "uniform"]),
                                   "mean": logs(1e-10, 1e-7)}),
            st.fixed_dictionaries({"distribution": st.just("list"), "values": st.lists(
                logs(1e-10, 1e-7), min_size=size - 1, max_size=size - 1)})))
    if draw(st.integers(0, 3)) == 0:
        raw["integrator"] = pick(st.fixed_dictionaries(
            {"method": st.sampled_from(["adaptive", "auto"] + ([] if wall else ["event"]))}),
            st.fixed_dictionaries({"method": st.sampled_from(["rk4", "event", "x"]),
                                   "dt": logs(1e-15, 1e-6), "tolerance": logs(1e-14, 1.0)}))
    if draw(st.integers(0, 3)) == 0:
        raw["probes"] = pick(st.just([2, size]),
                             st.lists(st.integers(0, size + 1), min_size=2, max_size=2))
    if not clean:
        for _ in range(draw(st.integers(0, 2))):            # a value anywhere
            section = draw(st.sampled_from(sorted(raw) + ["groove", "drag", "t_end", "zz"]))
            if isinstance(raw.get(section), dict) and draw(st.booleans()):
                raw[section][draw(st.text(max_size=6))] = draw(junk)
            else:
                raw[section] = draw(junk)
    return raw


def yaml_text(raw: dict, flow: bool, alias: bool) -> str:
    """The scene as YAML; ``alias``: a list's entries made one object, which PyYAML writes
    once with an anchor and then as aliases."""
    chain = raw.get("chain")
    if alias and isinstance(chain, dict):
        for key in ("materials", "radius"):
            if isinstance(chain.get(key), list) and chain[key]:
                chain[key] = [chain[key][0]] * len(chain[key])
    limit = sys.get_int_max_str_digits()
    sys.set_int_max_str_digits(0)                     # to write integers of any length
    try:
        return yaml.safe_dump(raw, default_flow_style=flow, allow_unicode=True)
    finally:
        sys.set_int_max_str_digits(limit)


def check_scene_text(text: str, tmp_path) -> None:
    """Through the loader and validator: a Scene or one SceneError naming a key; through
    the CLI's validate: exit 0, or exit 2 with one line naming the key."""
    t0 = time.perf_counter()
    try:
        raw = parse_yaml(text, "fuzz")
        if isinstance(raw, dict):
            scene_from_dict(raw)
    except SceneError as exc:
        assert exc.field and f"scene field '" in str(exc), str(exc)
    path = tmp_path / "fuzz.yaml"
    path.write_text(text, encoding="utf-8", errors="surrogatepass")
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main(["validate", str(path)])
    TIMES["scene"].append(time.perf_counter() - t0)
    assert rc in (0, 2), (rc, err.getvalue())
    if rc == 2:
        assert REFUSAL.match(err.getvalue()), err.getvalue()
    else:
        assert err.getvalue() == "" and "valid scene" in out.getvalue()


SCENE_SETTINGS = dict(deadline=None, derandomize=True,
                      suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                             HealthCheck.function_scoped_fixture])


@settings(max_examples=FAST_SCENES, **SCENE_SETTINGS)
@given(scenes(), st.booleans(), st.booleans())
def test_fuzzed_scenes_are_run_or_refused_in_one_line(tmp_path, raw, flow, alias):
    check_scene_text(yaml_text(raw, flow, alias), tmp_path)


@pytest.mark.slow
@settings(max_examples=SLOW_SCENES, **dict(SCENE_SETTINGS, derandomize=False))
@given(scenes(), st.booleans(), st.booleans())
def test_many_fuzzed_scenes_are_run_or_refused_in_one_line(tmp_path, raw, flow, alias):
    check_scene_text(yaml_text(raw, flow, alias), tmp_path)


@settings(max_examples=FAST_SCENES, **SCENE_SETTINGS)
@given(scenes())
def test_fuzzed_scene_mappings_are_validated_or_refused(raw):
    """The same mappings given to the validator directly (as a program does, through
    Scene.derive or scene_from_dict): a Scene or one SceneError naming a key."""
    try:
        scene_from_dict(raw)
    except SceneError as exc:
        assert exc.field and "\n" not in exc.problem and len(str(exc)) < 1200, str(exc)


@pytest.mark.slow
@settings(max_examples=SLOW_SCENES, **dict(SCENE_SETTINGS, derandomize=False))
@given(scenes())
def test_many_fuzzed_scene_mappings_are_validated_or_refused(raw):
    test_fuzzed_scene_mappings_are_validated_or_refused.hypothesis.inner_test(raw)


def test_the_scene_strategy_reaches_both_answers(tmp_path):
    """The strategy is no use if it only builds refusals (or only valid scenes): over a
    fixed sample, both occur, and so do the field chains' keys."""
    answers, keys = set(), set()

    @settings(max_examples=60, derandomize=True, deadline=None, database=None,
              suppress_health_check=list(HealthCheck))
    @given(scenes())
    def sample(raw):
        keys.update(f"{k}.{s}" if isinstance(v, dict) else k for k, v in raw.items()
                    for s in (v if isinstance(v, dict) else [None]))
        try:
            scene_from_dict(raw)
            answers.add("valid")
        except SceneError:
            answers.add("refused")
    sample()
    assert answers == {"valid", "refused"}
    assert {"chain.n", "walls.end", "precompression.force", "striker.velocity"} <= keys


# --- measurement CSVs -----------------------------------------------------------------
cells = st.one_of(
    logs(1e-9, 1e3).map(repr), st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.sampled_from(["", " ", "nan", "-1", "0", "1e400", "abc", '"1,2"', '"a""b"', "1\t2"]),
    st.text(max_size=6))
headers = st.lists(st.one_of(st.sampled_from(COLUMNS), st.text(max_size=8)), min_size=0,
                   max_size=7)


@st.composite
def csv_texts(draw) -> bytes:
    """A measurement file: half of them well formed (the required columns, one positive
    number per cell), the others with any header, ragged rows and cells of any kind."""
    if draw(st.booleans()):
        header = ["v_striker_m_s", draw(st.sampled_from(["dt_peak_s", "dt_front_s"]))] + draw(
            st.lists(st.sampled_from(["dt_err_s", "chain_id", "vmax_1_m_s", "vmax_2_m_s",
                                      "vmax_err_m_s"]), unique=True, max_size=3))
        rows = draw(st.lists(st.lists(logs(1e-7, 1.0).map(repr), min_size=len(header),
                                      max_size=len(header)), min_size=1, max_size=6))
    else:
        header = draw(headers)
        rows = draw(st.lists(st.lists(cells, min_size=max(0, len(header) - 1),
                                      max_size=len(header) + 1), max_size=6))
    lines = [",".join(header)] + [",".join(r) for r in rows]
    if draw(st.booleans()):
        lines.insert(draw(st.integers(0, len(lines))), "# a comment")
    text = "\n".join(lines) + draw(st.sampled_from(["\n", "", "\r\n"]))
    data = text.encode("utf-8", "surrogatepass")
    if draw(st.integers(0, 5)) == 0:
        data = b"\xef\xbb\xbf" + data                    # a byte-order mark
    if draw(st.integers(0, 8)) == 0:
        data += b"\xff"                                  # not UTF-8
    return data


def check_csv(data: bytes, peaks: bool, tmp_path) -> None:
    """read_measurements: Measurements, or one GranchainError on one line naming the file."""
    path = tmp_path / "m.csv"
    path.write_bytes(data)
    t0 = time.perf_counter()
    try:
        m = read_measurements(path, peaks=peaks)
        assert len(m.v) >= 1 and (m.v > 0).all() and (m.t > 0).all()
    except GranchainError as exc:
        msg = str(exc)
        assert "\n" not in msg and msg.startswith(str(path)), msg
    TIMES["csv"].append(time.perf_counter() - t0)


@settings(max_examples=FAST_CSVS, **SCENE_SETTINGS)
@given(csv_texts(), st.booleans())
def test_fuzzed_measurement_files_are_read_or_refused_in_one_line(tmp_path, data, peaks):
    check_csv(data, peaks, tmp_path)


@pytest.mark.slow
@settings(max_examples=SLOW_CSVS, **dict(SCENE_SETTINGS, derandomize=False))
@given(csv_texts(), st.booleans())
def test_many_fuzzed_measurement_files_are_read_or_refused_in_one_line(tmp_path, data, peaks):
    check_csv(data, peaks, tmp_path)


def test_the_csv_strategy_reaches_both_answers(tmp_path):
    """Over a fixed sample the CSV strategy gives files that are read and files refused."""
    answers = set()

    @settings(max_examples=80, derandomize=True, deadline=None, database=None,
              suppress_health_check=list(HealthCheck))
    @given(csv_texts())
    def sample(data):
        (tmp_path / "m.csv").write_bytes(data)
        try:
            read_measurements(tmp_path / "m.csv")
            answers.add("read")
        except GranchainError:
            answers.add("refused")
    sample()
    assert answers == {"read", "refused"}


def teardown_module():
    for what, ts in TIMES.items():
        if ts:
            print(f"\nfuzz {what}: {len(ts)} examples, {sum(ts):.2f} s, longest {max(ts):.3f} s")
