"""The tutorials (docs/tutorials/*.md) run as written.

Each page's blocks are taken in order (the convention is at the top of
docs/tutorials/index.md): a ```console block's ``$ `` lines are commands (continued
by a trailing backslash or by ``> `` lines), each run with ``bash -o pipefail -c`` in one
temporary working directory per page; a
```{code-block} with a ``:caption:`` writes its body to the file the caption names before
the next command. ``$GRANCHAIN_REPO`` is this repository. A command that exits non-zero
fails the page's test with the command and its output. Commands in blocks of class
``slurm`` need a SLURM cluster: the page's ordinary test leaves them out, and
``test_slurm_page_on_the_cluster`` runs the whole page on the one-node test cluster.

The output a page shows under a command (its lines up to the next ``$ `` line; ``...``
stands for anything, a whole line of it for any lines) must be what the command printed,
stdout and stderr together: every shown line matches one printed line (a line of names,
as ``ls`` shows them on a terminal, may be printed one per line), in order, with
its words as shown and every number within ``NUMBER_TOLERANCE`` of the printed one, but
for the numbers ``NOT_COMPARED`` names, with its reason (wall times, job ids, rounding).
"""
from __future__ import annotations

import dataclasses
import math
import os
import re
import signal
import subprocess
from decimal import Decimal
from pathlib import Path

import pytest

from slurm_support import require_marks, slurm_cluster  # noqa: F401 (slurm_cluster is a fixture)

REPO = Path(__file__).resolve().parents[1]
TUTORIALS = REPO / "docs" / "tutorials"
INDEX = TUTORIALS / "index.md"
COMMAND_TIMEOUT_S = 900

# what each page runs (a page without an entry fails test_every_page_is_listed)
_slow, _workflow, _lammps = pytest.mark.slow, pytest.mark.workflow, pytest.mark.lammps
MARKS = {
    "reproduce-the-chapter": (_slow, _workflow, _lammps),
    "build-your-own-chain": (_slow,),
    "bring-your-measurements": (_slow,),
    "run-on-a-slurm-cluster": (_workflow,),
    "cross-validate-with-lammps": (_lammps,),
    "add-a-physical-effect": (_slow, _lammps),
}
SLURM_PAGE = "run-on-a-slurm-cluster"


@dataclasses.dataclass(frozen=True)
class Step:
    """One thing a page does: run ``command`` (``slurm``: only on a cluster) and print
    what ``shown`` shows (the page's lines under it, from ``shown_line`` on), or write
    ``text`` to ``path``. ``line``: where it is on the page."""
    line: int
    command: str | None = None
    path: str | None = None
    text: str = ""
    slurm: bool = False
    shown: tuple[str, ...] = ()
    shown_line: int = 0


# The numbers a page shows are compared with the ones the command printed: an integer
# (counts, steps, sizes) exactly; any other to within half a unit in the last digit the
# page shows (the command prints the same digits) or 1e-9 of its value, whichever is
# larger (rounding differences between machines: the engines agree to ~1e-10, so a value
# on a rounding boundary of 10 printed digits may come out one unit apart). A change of
# the physics shows: a 1 % change of the Hertz constant moves the printed delays and group
# velocities by ~0.4 %, tens of units of their last digit.
NUMBER_TOLERANCE = "half a unit in the last digit shown, or 1e-9 relative; integers exactly"
# pages that print numbers to 10 digits, with the relative tolerance that replaces 1e-9
# there and why
RELATIVE = {"cross-validate-with-lammps": (1e-6, "compare's table prints 10 digits of both "
                                           "engines' values, which another CPU, compiler "
                                           "or LAMMPS build moves by rounding")}

# Numbers of the shown output that are not compared: (page, regex on a shown line whose
# group ``x`` spans them, why). Every other number is.
NOT_COMPARED = [
    (None, r"\d steps, (?P<x>\S+) s$", "the run's wall time"),
    (None, r"members in (?P<x>\S+) s", "a batch's wall time"),
    (None, r"Job (?P<z>\d+) has been submitted with SLURM jobid (?P<x>\d+) \(log: .*/(?P<y>\d+)\.log\)",
     "snakemake's job number and SLURM's job id"),
    ("cross-validate-with-lammps", r"^v\(t\), every particle\s+\S+\s+\S+\s+(?P<x>\S+)",
     "the engines' difference: rounding"),
    ("cross-validate-with-lammps", r"energy balance error (?P<x>\S+) \(LAMMPS",
     "LAMMPS's balance closes by construction: what is left is rounding"),
    ("cross-validate-with-lammps", r"^(?:v_|dt_|work_|samples)\S*\s+\S+\s+\S+\s+(?P<x>\S+)",
     "the engines' difference: rounding, which depends on the CPU, compiler and MPI "
     "(compare's own tolerance column bounds it)"),
    ("cross-validate-with-lammps", r"^work_particle_friction\s+\S+\s+(?P<x>\S+)",
     "LAMMPS's residual of its balance: rounding"),
    ("cross-validate-with-lammps", r"member \d+\s+diff (?P<x>\S+)",
     "the engines' difference: rounding (its tolerance is shown beside it)"),
]


_FENCE = re.compile(r"^(`{3,}|~{3,})(.*)$")
_DIRECTIVE = re.compile(r"^\{(?:code-block|code|sourcecode)\}\s*(\S*)")


def _blocks(text: str):
    """(line of the opening fence, line of the body's first line, language, options, body
    lines) of every top-level fenced block, lines counted from 1; a longer fence may hold
    shorter ones (they are its body)."""
    lines = text.splitlines()
    i = 0
    while i < len(lines):
        m = _FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        fence, info, start = m.group(1), m.group(2).strip(), i
        body = []
        i += 1
        while i < len(lines) and not (lines[i].startswith(fence[0] * len(fence))
                                      and not lines[i].strip(fence[0]).strip()):
            body.append(lines[i])
            i += 1
        i += 1
        options, first = {}, start + 2
        d = _DIRECTIVE.match(info)
        if d:
            lang = d.group(1)
            while body and re.match(r"^:[\w-]+:", body[0]):
                key, _, value = body.pop(0)[1:].partition(":")
                options[key] = value.strip()
                first += 1
            if body and not body[0].strip():
                body.pop(0)
                first += 1
        else:
            lang = info.split()[0] if info else ""
        yield start + 1, first, lang, options, body


def steps(text: str) -> list[Step]:
    """The commands and files of a page, in order (see the module doc)."""
    out = []
    for line, first, lang, options, body in _blocks(text):
        if lang == "console":
            slurm = "slurm" in options.get("class", "").split()
            k = 0
            while k < len(body):
                if body[k].startswith("$ "):
                    at, cmd = first + k, body[k][2:]
                    while k + 1 < len(body) and (cmd.endswith("\\")
                                                 or body[k + 1].startswith("> ")
                                                 or body[k + 1] == ">"):
                        k += 1
                        nxt = body[k]
                        cmd += "\n" + (nxt[2:] if nxt.startswith(">") else nxt)
                    shown, shown_line = [], first + k + 1
                    while k + 1 < len(body) and not body[k + 1].startswith("$ "):
                        k += 1
                        shown.append(body[k])
                    out.append(Step(at, command=cmd.strip(), slurm=slurm,
                                    shown=tuple(shown), shown_line=shown_line))
                k += 1
        elif "caption" in options:
            path = options["caption"]
            assert not Path(path).is_absolute() and ".." not in Path(path).parts, \
                f"line {line}: a file block's caption must be a path inside the working " \
                f"directory, got {path!r}"
            out.append(Step(line, path=path, text="\n".join(body) + "\n"))
    return out


_NUMBER = re.compile(r"(?<![\w.])[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?(?!\w)")
_ELISION = "..."


def _pattern(shown: str) -> re.Pattern:
    """A shown output line as a pattern over a printed line: its numbers captured, ``...``
    any text, runs of blanks any blanks, everything else as written."""
    out, pos = [], 0
    for m in _NUMBER.finditer(shown):
        out.append(_literal(shown[pos:m.start()]))
        out.append(f"({_NUMBER.pattern})")
        pos = m.end()
    out.append(_literal(shown[pos:]))
    return re.compile("".join(out))


def _literal(text: str) -> str:
    return ".*?".join(r"\s+".join(re.escape(w) for w in re.split(r"\s+", part))
                      for part in text.split(_ELISION))


def number_agrees(shown: str, printed: str, rel: float = 1e-9) -> bool:
    """``NUMBER_TOLERANCE``: an integer exactly, else within half a unit of the last digit
    the page shows or ``rel`` of its value."""
    if re.fullmatch(r"[-+]?\d+", shown):
        return re.fullmatch(r"[-+]?\d+", printed) is not None and int(shown) == int(printed)
    unit = float(Decimal(1).scaleb(Decimal(shown).as_tuple().exponent))
    a, b = float(shown), float(printed)
    return math.isfinite(b) and abs(b - a) <= max(0.5 * unit * (1 + 1e-9), rel * abs(a))


def _not_compared(page: str, line: str) -> list[tuple[int, int]]:
    """Spans of ``line`` whose numbers ``NOT_COMPARED`` exempts."""
    spans = []
    for name, rx, _ in NOT_COMPARED:
        if name in (None, page):
            for m in re.finditer(rx, line):
                spans += [m.span(g) for g in m.groupdict() if m.group(g) is not None]
    return spans


def check_shown_output(page: str, step: Step, printed: str) -> int:
    """Every shown line of ``step`` in ``printed``, in order, its numbers agreeing; returns
    the number of numbers compared. Raises AssertionError naming the page line."""
    lines = [ln.strip() for ln in printed.splitlines()]
    rel = RELATIVE.get(page, (1e-9,))[0]
    at, compared = 0, 0
    for k, shown in enumerate(step.shown):
        shown = shown.strip()
        if not shown or shown == _ELISION:
            continue
        where = f"{page}.md:{step.shown_line + k}"
        rx = _pattern(shown)
        skip = _not_compared(page, shown)
        wanted = [(i, n.group()) for i, n in enumerate(_NUMBER.finditer(shown))
                  if not any(a <= n.start() < b for a, b in skip)]

        def differ(m):
            """The numbers of a printed line matching the shown one's words that do not
            agree with the page's: [(shown, printed)]."""
            return [(w, m.group(i + 1)) for i, w in wanted
                    if not number_agrees(w, m.group(i + 1), rel)]

        found, near = None, None
        # one printed line; or, for a line of names as ls prints them off a terminal,
        # several joined
        for used in (1, *(range(2, 51) if _ELISION not in shown else ())):
            for j in range(at, len(lines) - used + 1):
                m = rx.fullmatch(" ".join(lines[j:j + used]))
                if m is None:
                    continue
                bad = differ(m)
                if not bad:
                    found = (j, used)
                    break
                near = near or (lines[j], bad)
            if found or near or used >= len(lines) - at:
                break
        if found is None:
            if near:
                raise AssertionError(f"{where}: the page shows {shown!r}, the command printed "
                                     f"{near[0]!r}: numbers (page, printed) {near[1]}")
            raise AssertionError(f"{where}: no printed line (after the {at} matched before) "
                                 f"is {shown!r}")
        at = found[0] + found[1]
        compared += len(wanted)
    return compared


def pages() -> list[Path]:
    return sorted(p for p in TUTORIALS.glob("*.md") if p != INDEX)


def _run(command: str, cwd: Path, env: dict) -> subprocess.CompletedProcess:
    """``bash -o pipefail -c command`` in its own session, killed whole on the timeout;
    stdout and stderr together, in the order printed, as a terminal shows them."""
    proc = subprocess.Popen(["bash", "-o", "pipefail", "-c", command], cwd=cwd, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            start_new_session=True)
    try:
        out, _ = proc.communicate(timeout=COMMAND_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        out, _ = proc.communicate()
        out += f"\n(killed after {COMMAND_TIMEOUT_S} s)"
    return subprocess.CompletedProcess(command, proc.returncode, out)


def run_page(page: Path, work: Path, with_slurm: bool) -> tuple[int, int]:
    """Run the page's steps in ``work``, checking each command's shown output; returns
    (commands run, numbers compared)."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("SLURM_")}
    env.update(GRANCHAIN_REPO=str(REPO), MPLBACKEND="Agg")
    ran = compared = 0
    for st in steps(page.read_text()):
        where = f"{page.relative_to(REPO)}:{st.line}"
        if st.path is not None:
            target = work / st.path
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_text(st.text)
            continue
        if st.slurm and not with_slurm:
            continue
        if "snakemake" in st.command:
            require_marks(f"snakemake ({where})", "workflow", *(("slurm",) if st.slurm else ()))
        proc = _run(st.command, work, env)
        ran += 1
        if proc.returncode != 0:
            pytest.fail(f"{where}: exit {proc.returncode}\n$ {st.command}\n--- output ---\n"
                        f"{proc.stdout[-8000:]}", pytrace=False)
        try:
            compared += check_shown_output(page.stem, st, proc.stdout)
            wrong = None
        except AssertionError as exc:
            wrong = str(exc)
        if wrong:
            pytest.fail(f"{wrong}\n$ {st.command}\n--- output ---\n{proc.stdout[-6000:]}",
                        pytrace=False)
    return ran, compared


# ---------------------------------------------------------------------------------------
# the pages' shape (no command runs)
# ---------------------------------------------------------------------------------------
def test_every_page_is_listed_and_runs_commands():
    """Every page is in the index's toctree and in MARKS, and has a command the ordinary
    test runs (a page whose blocks use another info string has none)."""
    toctree = re.search(r"```\{toctree\}\n(.*?)```", INDEX.read_text(), re.S).group(1)
    listed = [ln.strip() for ln in toctree.splitlines() if ln.strip() and not ln.startswith(":")]
    names = [p.stem for p in pages()]
    assert sorted(listed) == sorted(names), (listed, names)
    assert sorted(MARKS) == sorted(names), "add the page to MARKS with what it runs"
    for p in pages():
        local = [s for s in steps(p.read_text()) if s.command and not s.slurm]
        assert local, f"{p.name}: no ```console block with a '$ ' command outside class slurm"


def test_steps_follow_the_convention():
    text = "\n".join([
        "```console", "$ echo a \\", "    b", "a b", "$ cat <<'EOF'", "> x", ">", "> EOF", "```",
        "```bash", "$ not run", "```",
        "```{code-block} yaml", ":caption: sub/x.yaml", "", "k: 1", "```",
        "```{code-block} console", ":class: slurm", "", "$ sbatch job.sh", "```",
        "````markdown", "```console", "$ inside an example", "```", "````",
        "```yaml", "not: a file", "```",
    ])
    assert steps(text) == [Step(2, command="echo a \\\n    b", shown=("a b",), shown_line=4),
                           Step(5, command="cat <<'EOF'\nx\n\nEOF", shown_line=9),
                           Step(13, path="sub/x.yaml", text="k: 1\n"),
                           Step(21, command="sbatch job.sh", slurm=True, shown_line=22)]


# ---------------------------------------------------------------------------------------
# every page, executed
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", [pytest.param(n, marks=m) for n, m in MARKS.items()])
def test_page_runs(name, tmp_path):
    page = TUTORIALS / f"{name}.md"
    ran, compared = run_page(page, tmp_path, with_slurm=False)
    assert ran > 0
    # every number shown is compared but those NOT_COMPARED names
    shown = sum(len(_NUMBER.findall(" ".join(s.shown))) for s in steps(page.read_text())
                if s.command and not s.slurm)
    exempt = sum(sum(1 for n in _NUMBER.finditer(ln.strip())
                     if any(a <= n.start() < b for a, b in _not_compared(name, ln.strip())))
                 for s in steps(page.read_text()) if s.command and not s.slurm for ln in s.shown)
    assert compared == shown - exempt, (compared, shown, exempt)


@pytest.mark.slurm
@pytest.mark.workflow
@pytest.mark.slow
def test_slurm_page_on_the_cluster(slurm_cluster, tmp_path):
    """The SLURM tutorial with its cluster commands, on the one-node test cluster."""
    page = TUTORIALS / f"{SLURM_PAGE}.md"
    assert any(s.slurm for s in steps(page.read_text()))
    assert run_page(page, tmp_path, with_slurm=True)[0] > 0
