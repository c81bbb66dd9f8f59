"""Which code lines of the package name a physical effect.

A line names an effect when one of its code tokens (a name, or a string literal, f-strings
included; comments and docstrings are not code) holds, as a word, the name of an effect
of ``granchain.effects.SPECS`` or one of the slots, columns and ledger entries its
``EffectSpec`` declares (``P_GROOVE_S``, ``work_air_J``, ...). A word ends at anything
that is not a letter or digit, so ``G_HERTZ_K``, ``terms.air_drag`` and ``"Hertz
contact"`` name an effect, ``Hertzian`` and ``rotational`` do not. Case is ignored.

    python -m tests.effect_names granchain/engines granchain/lammps ...

prints the lines and their count per file.
"""
from __future__ import annotations

import io
import re
import sys
import tokenize
from pathlib import Path

from granchain.effects import SPECS

ROOT = Path(__file__).resolve().parents[1]


def _words() -> set[str]:
    """The effects' names and their declared slots, columns and ledger entries."""
    out = set()
    for s in SPECS.values():
        out.add(s.name)
        out.update(s.params + s.flags + s.rows + tuple(b for b, _ in s.state))
        out.update(w for w in (s.work_slot, s.work_code, s.work, s.table_column) if w)
    return out


PATTERN = re.compile(r"(?<![A-Za-z0-9])(" + "|".join(sorted(map(re.escape, _words()), key=len,
                                                              reverse=True))
                     + r")(?![A-Za-z0-9])", re.IGNORECASE)
_SKIP = (tokenize.COMMENT, tokenize.NL, tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT,
         tokenize.ENDMARKER)
_TEXT = {tokenize.NAME, tokenize.STRING} | {getattr(tokenize, t) for t in
                                            ("FSTRING_START", "FSTRING_MIDDLE", "FSTRING_END")
                                            if hasattr(tokenize, t)}


def _docstring(toks, i) -> bool:
    """Is token i a string statement of its own (a docstring)?"""
    j = i - 1
    while j >= 0 and toks[j].type in (tokenize.COMMENT, tokenize.NL):
        j -= 1
    if j >= 0 and toks[j].type not in (tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT):
        return False
    k = i + 1
    while k < len(toks) and toks[k].type == tokenize.COMMENT:
        k += 1
    return k == len(toks) or toks[k].type in (tokenize.NEWLINE, tokenize.ENDMARKER)


def naming_lines(path: Path) -> list[tuple[int, str]]:
    """(line number, line) of each code line of a Python file that names an effect."""
    src = path.read_text()
    toks = list(tokenize.generate_tokens(io.StringIO(src).readline))
    hits: set[int] = set()
    for i, t in enumerate(toks):
        if t.type in _SKIP or t.type not in _TEXT:
            continue
        if t.type == tokenize.STRING and _docstring(toks, i):
            continue
        if PATTERN.search(t.string):
            hits.update(range(t.start[0], t.end[0] + 1) if t.type != tokenize.NAME
                        else (t.start[0],))
    lines = src.splitlines()
    return [(k, lines[k - 1]) for k in sorted(hits)]


def files(*paths: str) -> list[Path]:
    """The Python files of these repository-relative paths (files, folders, or glob
    patterns)."""
    out = []
    for p in paths:
        q = ROOT / p
        if "*" in p:
            out += sorted(ROOT.glob(p))
        elif q.is_dir():
            out += sorted(f for f in q.rglob("*.py") if "__pycache__" not in f.parts)
        else:
            out.append(q)
    return out


def count(*paths: str) -> dict[str, int]:
    """Effect-naming code lines per file (files with none left out)."""
    return {str(f.relative_to(ROOT)): len(h) for f in files(*paths) if (h := naming_lines(f))}


# The engine side: every module that runs, plans or reads a scene's physics without
# being an effect.
ENGINE_SIDE = ("granchain/engines", "granchain/lammps", "granchain/columns.py",
               "granchain/reductions", "granchain/stoprule.py", "granchain/scene.py",
               "granchain/scenecheck.py", "granchain/scenekeys.py", "granchain/scenefile.py",
               "granchain/runplan.py", "granchain/costmodel.py", "granchain/observables.py", "granchain/compare.py",
               "granchain/simulate.py", "granchain/guards.py", "granchain/tables.py",
               "granchain/trajectory.py")


if __name__ == "__main__":
    total = 0
    for f in files(*(sys.argv[1:] or ENGINE_SIDE)):
        for k, line in naming_lines(f):
            print(f"{f.relative_to(ROOT)}:{k}: {line.strip()}")
            total += 1
    print(total, "lines")
