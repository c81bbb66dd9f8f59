"""The tutorials (docs/tutorials/*.md) run as written.

Each page's blocks are taken in order (the convention is at the top of
docs/tutorials/index.md): a ```console block's ``$ `` lines are commands (continued
by a trailing backslash or by ``> `` lines), each run with ``bash -o pipefail -c`` in one
temporary working directory per page; a
```{code-block} with a ``:caption:`` writes its body to the file the caption names before
the next command. ``$GRANCHAIN_REPO`` is this repository. A command that exits non-zero
fails the page's test with the command and its stderr. Commands in blocks of class
``slurm`` need a SLURM cluster: the page's ordinary test leaves them out, and
``test_slurm_page_on_the_cluster`` runs the whole page on the one-node test cluster.
"""
from __future__ import annotations

import dataclasses
import os
import re
import signal
import subprocess
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
    """One thing a page does: run ``command`` (``slurm``: only on a cluster), or write
    ``text`` to ``path``. ``line``: where it is on the page."""
    line: int
    command: str | None = None
    path: str | None = None
    text: str = ""
    slurm: bool = False


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
                    out.append(Step(at, command=cmd.strip(), slurm=slurm))
                k += 1
        elif "caption" in options:
            path = options["caption"]
            assert not Path(path).is_absolute() and ".." not in Path(path).parts, \
                f"line {line}: a file block's caption must be a path inside the working " \
                f"directory, got {path!r}"
            out.append(Step(line, path=path, text="\n".join(body) + "\n"))
    return out


def pages() -> list[Path]:
    return sorted(p for p in TUTORIALS.glob("*.md") if p != INDEX)


def _run(command: str, cwd: Path, env: dict) -> subprocess.CompletedProcess:
    """``bash -o pipefail -c command`` in its own session, killed whole on the timeout."""
    proc = subprocess.Popen(["bash", "-o", "pipefail", "-c", command], cwd=cwd, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    try:
        out, err = proc.communicate(timeout=COMMAND_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        out, err = proc.communicate()
        err += f"\n(killed after {COMMAND_TIMEOUT_S} s)"
    return subprocess.CompletedProcess(command, proc.returncode, out, err)


def run_page(page: Path, work: Path, with_slurm: bool) -> int:
    """Run the page's steps in ``work``; returns the number of commands run."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("SLURM_")}
    env.update(GRANCHAIN_REPO=str(REPO), MPLBACKEND="Agg")
    ran = 0
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
            pytest.fail(f"{where}: exit {proc.returncode}\n$ {st.command}\n--- stderr ---\n"
                        f"{proc.stderr[-6000:]}\n--- stdout ---\n{proc.stdout[-3000:]}",
                        pytrace=False)
    return ran


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
    assert steps(text) == [Step(2, command="echo a \\\n    b"),
                           Step(5, command="cat <<'EOF'\nx\n\nEOF"), Step(13, path="sub/x.yaml", text="k: 1\n"),
                           Step(21, command="sbatch job.sh", slurm=True)]


# ---------------------------------------------------------------------------------------
# every page, executed
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", [pytest.param(n, marks=m) for n, m in MARKS.items()])
def test_page_runs(name, tmp_path):
    page = TUTORIALS / f"{name}.md"
    assert run_page(page, tmp_path, with_slurm=False) > 0


@pytest.mark.slurm
@pytest.mark.workflow
@pytest.mark.slow
def test_slurm_page_on_the_cluster(slurm_cluster, tmp_path):
    """The SLURM tutorial with its cluster commands, on the one-node test cluster."""
    page = TUTORIALS / f"{SLURM_PAGE}.md"
    assert any(s.slurm for s in steps(page.read_text()))
    run_page(page, tmp_path, with_slurm=True)
