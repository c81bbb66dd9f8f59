"""The JSON text of ``granchain run`` (``fileio.json_text``): byte for byte what the standard
library's ``json.dumps`` writes for the same document with non-finite floats as null, on
the documents ``granchain run`` builds for scenes with peaks not final (NaN), an end wall,
spheres of different sizes and materials, a vibrometer, ensembles and the event method,
and on documents made to reach every branch of the writer."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from conftest import SCENES
from granchain import cli, fileio
from granchain.commands import output as command_output


def _oracle_jsonable(obj):
    """Non-finite floats -> None, tuples -> lists (how the CLI has always prepared its
    documents for ``json.dumps``)."""
    if isinstance(obj, float):
        return None if not math.isfinite(obj) else obj
    if isinstance(obj, dict):
        return {k: _oracle_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_oracle_jsonable(v) for v in obj]
    return obj


def _oracle(doc, indent=None) -> str:
    return json.dumps(_oracle_jsonable(doc), indent=indent)


GAPS = str(SCENES / "gaps-20nm-440c.yaml")
PACKED = str(SCENES / "packed-440c.yaml")
RUNS = {
    # peaks cut off by a short t_end (NaN, not final), an ensemble of Verlet chains
    "cut ensemble": [GAPS, "--set=ensemble.realisations=5", "--set=integrator.method=verlet",
                     "--set=t_end=3e-6"],
    "ensemble": [GAPS, "--set=ensemble.realisations=3", "--set=integrator.method=verlet"],
    "event": [GAPS, "--set=ensemble.realisations=2", "--set=integrator.method=event"],
    # an end wall whose peak a short t_end cuts off
    "wall": [PACKED, "--set=walls.end=rigid", "--set=t_end=1e-5"],
    "heterogeneous": [PACKED, "--set=chain.n=5", "--set=probes=[2,5]",
                      "--set=chain.radius=[1.5e-4,1e-4,1.5e-4,1e-4,1.5e-4]",
                      "--set=chain.materials=[ss440c,brass,ss440c,brass,ss440c]",
                      "--set=material=null"],
    "measured": [PACKED, "--set=chain.n=8", "--set=probes=[2,7]",
                 "--set=measurement.filter=bessel"],
}


@pytest.fixture
def spy(monkeypatch):
    """Every (document, indent, text) the CLI writes through ``json_text``."""
    calls = []

    def text(doc, indent=None):
        out = fileio.json_text(doc, indent)
        calls.append((doc, indent, out))
        return out
    monkeypatch.setattr(command_output, "json_text", text)
    return calls


@pytest.mark.parametrize("name", list(RUNS))
def test_run_json_file_is_the_standard_library_text(name, tmp_path, spy):
    out = tmp_path / "out.json"
    assert cli.main(["run", *RUNS[name], "--json", "--out", str(out)]) == 0
    (doc, indent, text), = spy
    assert indent == 1
    assert text == _oracle(doc, 1)
    assert out.read_bytes() == (_oracle(doc, 1) + "\n").encode()
    flat = json.dumps(doc)          # NaN where the document has a non-finite float
    if name in ("cut ensemble", "wall"):
        assert "NaN" in flat and "null" in text
    if name == "measured":
        assert '"measured": true' in text
    if name == "heterogeneous":
        assert len(doc["v_max"]) == 5


def test_run_json_stdout_is_the_standard_library_text(capsys, spy):
    assert cli.main(["run", *RUNS["cut ensemble"], "--json"]) == 0
    (doc, indent, text), = spy
    assert indent is None
    assert capsys.readouterr().out == _oracle(doc) + "\n"
    assert "NaN" in json.dumps(doc) and "NaN" not in text


class _Key(int):
    pass


DOCS = [
    1, -0.0, 1.5, math.nan, -math.inf, True, None, "a\nb\u00e9\"\\", [], {}, [[]], [{}], {"a": {}},
    {"a": [1, 2.0, None, True, False, "x", math.inf]},
    {"k": [{"x": [1, [2, [3]]]}, (1, 2)], "n": np.float64(0.1),
     "m": [np.float64(-np.inf), 1, np.float64(2.5)]},
    {1: 2, "b": {2.5: math.nan, None: [math.nan]}},
    [{"a": 1}, [], {}, ()], {"r": [0.1, -0.0, 1e300, 5e-324, 2**70, -(2**70)]},
    [math.nan, 1.0, -math.inf], [math.nan], (True, False), {"z": _Key(3), "y": [_Key(4)]},
    {"deep": {"deeper": {"deepest": [[1.0, [math.nan, {"q": "\u2603"}]]]}}},
]


@pytest.mark.parametrize("indent", [None, 0, 1, 2, 4])
@pytest.mark.parametrize("doc", DOCS, ids=range(len(DOCS)))
def test_json_text_equals_json_dumps(doc, indent):
    assert fileio.json_text(doc, indent) == _oracle(doc, indent)
    assert fileio.jsonable(doc) == _oracle_jsonable(doc)


@pytest.mark.parametrize("bad", [np.int64(3), {"x": np.array([1.0])}, [1.0, object()],
                                 {"a": [np.bool_(True)]}])
def test_what_json_dumps_refuses_is_refused(bad):
    for indent in (None, 1):
        with pytest.raises(TypeError) as want:
            _oracle(bad, indent)
        with pytest.raises(TypeError) as got:
            fileio.json_text(bad, indent)
        assert str(got.value) == str(want.value)
