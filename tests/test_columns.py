"""granchain.columns documents every column the tables can have and every key of the JSON
documents the tools write, and nothing else; its Markdown page builds under Sphinx -W."""
from __future__ import annotations

import dataclasses
import itertools
import subprocess
import sys
from pathlib import Path

import pandas as pd
from markdown_it import MarkdownIt

from granchain import columns, tables
from granchain.inference import Inference, JointInference
from granchain.observables import LEDGER_ENTRIES, ChainResult

CONFIG = Path(__file__).resolve().parents[1] / "config" / "config.yaml"
SIZES = (1, 2, 9, 10, 99, 100, 150)
FLAGS = list(itertools.product((False, True), repeat=2))
SETTINGS = [s for k in range(len(tables.SETTING_COLUMNS) + 1)
            for s in itertools.combinations(tables.SETTING_COLUMNS, k)]


def _member_columns() -> set[str]:
    return {c for n in SIZES for (measured, walled) in FLAGS for settings in SETTINGS
            for c in tables.columns(n, measured, walled, settings)}


def _summary_columns() -> set[str]:
    return {c for (measured, walled) in FLAGS for settings in SETTINGS
            for c in tables.summary_columns(measured, walled, settings)}


def test_every_member_column_is_documented_and_every_entry_is_a_column():
    produced = _member_columns()
    missing = sorted(c for c in produced if columns.member_column(c) is None)
    assert not missing, f"columns without an entry in granchain.columns.MEMBER: {missing}"
    assert set(columns.MEMBER) <= produced, sorted(set(columns.MEMBER) - produced)
    for name, (pattern, _) in columns.MEMBER_PATTERNS.items():
        assert any(pattern.fullmatch(c) for c in produced), name


def test_every_summary_column_is_documented_and_every_entry_is_a_column():
    produced = _summary_columns()
    missing = sorted(c for c in produced if columns.summary_column(c) is None)
    assert not missing, f"summary columns without an entry: {missing}"
    assert set(columns.SUMMARY) <= produced, sorted(set(columns.SUMMARY) - produced)
    for name, (pattern, _) in columns.SUMMARY_PATTERNS.items():
        assert any(pattern.fullmatch(c) and c not in columns.SUMMARY for c in produced), name


def test_a_new_column_without_an_entry_is_found():
    assert columns.member_column("v_max_3_m_s") is None
    assert columns.summary_column("v_max_3_m_s_mean") is None      # observable not documented
    assert columns.summary_column("v_max_2_m_s_p50") is not None


def test_timing_columns_are_documented():
    assert set(columns.TIMING) == set(tables.TIMING_COLUMNS)


def test_run_json_keys_are_documented():
    keys = {f.name for f in dataclasses.fields(ChainResult)} | {"scene", "scene_hash", "runs"}
    assert set(columns.RUN_JSON) == keys
    assert set(columns.LEDGER_JSON) == set(LEDGER_ENTRIES)


def _json_keys(cls) -> set[str]:
    """The keys of a result's to_json (dummy field values: only the keys matter), plus the
    ``measurements`` key granchain infer adds."""
    res = cls(**{f.name: () for f in dataclasses.fields(cls)})
    return set(res.to_json()) | {"measurements"}


def test_infer_json_keys_are_documented():
    assert set(columns.INFER_JSON) == _json_keys(Inference)
    assert set(columns.INFER_JOINT_JSON) == _json_keys(JointInference)


def test_study_provenance_keys_are_documented():
    from granchain import workflow as gw
    from granchain.workflow.gather import study_provenance
    keys = set(tables.environment()) | {"lammps_version"}
    df = pd.DataFrame({"seed": [1], "engine": ["reference"], "method": ["verlet"],
                       "dt_s": [1e-9]})
    for preset in ("tiny", "default"):
        P = gw.load_config(CONFIG,
                           preset)[1]
        for study in gw.preset_studies(P):
            keys |= set(study_provenance(preset, P, study, gw.study_scenes(P, study), df))
    assert set(columns.PROVENANCE_JSON) == keys


def test_member_types_agree_with_the_study_table():
    """The types study_table gives its columns are the documented ones."""
    n = 3
    cols = tables.columns(n)
    row = {c: ("x" if columns.member_column(c).dtype == "string" else 1.0) for c in cols}
    df = tables.study_table([row], n)
    for c in ("realisation", "seed", "steps", "force_evaluations"):
        assert columns.member_column(c).dtype == "int" and df[c].dtype == "int64"
    assert columns.member_column("wave_arrived").dtype == "bool" and df["wave_arrived"].dtype == bool


# ---------------------------------------------------------------------------------------
# the Markdown page
# ---------------------------------------------------------------------------------------
def _tables_of(text: str) -> list[list[list[str]]]:
    """Each table of a Markdown text as rows of cell texts (header first)."""
    tokens = MarkdownIt("commonmark").enable("table").parse(text)
    out, row = [], None
    for tok in tokens:
        if tok.type == "table_open":
            out.append([])
        elif tok.type == "tr_open":
            row = []
        elif tok.type == "inline" and row is not None:
            row.append(tok.content)
        elif tok.type == "tr_close":
            out[-1].append(row)
            row = None
    return out


def test_reference_page_lists_every_entry_in_well_formed_tables():
    text = tables.column_reference_markdown()
    lines = text.splitlines()
    assert lines[0].startswith("# ") and sum(ln.startswith("# ") for ln in lines) == 1
    found = _tables_of(text)
    assert len(found) == len(columns.SECTIONS)
    for rows, (heading, _, entries, patterns) in zip(found, columns.SECTIONS):
        assert rows[0] == ["name", "type", "unit", "description"], heading
        assert all(len(r) == 4 for r in rows), heading
        names = [r[0].strip("`") for r in rows[1:]]
        assert names == list(entries) + list(patterns), heading


def test_a_pipe_in_a_description_stays_in_its_cell(monkeypatch):
    monkeypatch.setitem(columns.TIMING, "wall_s", columns.Column("float", "s", "a | b"))
    rows = next(r for r, s in zip(_tables_of(columns.reference_markdown()), columns.SECTIONS)
                if s[2] is columns.TIMING)
    assert all(len(r) == 4 for r in rows)
    assert [r[3].replace("\\", "") for r in rows if r[0] == "`wall_s`"] == ["a | b"]


def test_reference_page_builds_under_sphinx_warnings_as_errors(tmp_path):
    src = tmp_path / "src"
    src.mkdir()
    (src / "conf.py").write_text('extensions = ["myst_parser"]\nproject = "t"\n')
    (src / "index.md").write_text(tables.column_reference_markdown())
    proc = subprocess.run([sys.executable, "-m", "sphinx", "-W", "-q", "-b", "html",
                           str(src), str(tmp_path / "out")], capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr


def test_engine_comparison_columns_are_documented():
    """The comparison table's columns are granchain.compare's rows behind the scene's
    columns, and each has exactly one entry."""
    from granchain.compare import ROW_COLUMNS
    from granchain.workflow.lammps_check import TABLE_COLUMNS
    assert TABLE_COLUMNS[5:] == tuple("v_striker_m_s" if c == "v_striker" else c
                                      for c in ROW_COLUMNS)
    assert tuple(columns.COMPARISON) == TABLE_COLUMNS


def test_vibrometer_and_accuracy_columns_are_documented():
    """The accuracy study's columns each have exactly one entry, in table order, and a
    column the vibrometer table shares with the per-member table means the same there.
    (The vibrometer table's columns are its documented list; tests/test_workflow.py's
    tiny vibrometer study checks that the rows it writes have exactly those keys.)"""
    from granchain.accuracy.harness import COLUMNS
    assert tuple(columns.ACCURACY) == COLUMNS
    shared = [c for c in columns.VIBROMETER if c in columns.MEMBER and c not in columns._VIB_OWN]
    assert shared and all(columns.VIBROMETER[c] is columns.MEMBER[c] for c in shared)
