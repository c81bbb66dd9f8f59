"""The documentation: the README stays a front page, every relative link in it and in the
docs resolves, and the Sphinx site builds from the code with no warning (the slow test is
how CI builds the site)."""
from __future__ import annotations

import importlib.util
import os
import re
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
DOCS = REPO / "docs"
README_LIMIT = 8000
# [text](target) and ![alt](target), target up to a space or the closing parenthesis
LINK = re.compile(r"!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")


def generated_pages() -> set[Path]:
    """The reference pages the build writes from the code (not in the repository)."""
    spec = importlib.util.spec_from_file_location("docs_generated",
                                                  DOCS / "_ext" / "generated.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return {(DOCS / page).resolve() for page in mod.GENERATED}


def markdown_files() -> list[Path]:
    return [REPO / "README.md"] + sorted(p for p in DOCS.rglob("*.md")
                                         if "_build" not in p.relative_to(DOCS).parts)


def relative_links(text: str) -> list[str]:
    """Link targets that are paths in the repository: no scheme, not a bare #anchor;
    fenced code blocks are not prose and are skipped."""
    text = re.sub(r"(?ms)^(```|~~~).*?^\1", "", text)
    out = []
    for target in LINK.findall(text):
        if re.match(r"^[a-zA-Z][a-zA-Z0-9+.-]*:", target) or target.startswith("#"):
            continue
        out.append(target.split("#", 1)[0])
    return out


def test_readme_is_a_front_page():
    text = (REPO / "README.md").read_text(encoding="utf-8")
    assert len(text) <= README_LIMIT, (
        f"README.md has {len(text)} characters, above {README_LIMIT}: move the detail to "
        "a page under docs/ and link it")


def test_link_checker_finds_relative_links():
    text = ("[a](docs/x.md) [b](https://example.org) [c](#top) ![d](fig.png#k)\n"
            "```\n[e](inside/code.md)\n```\n")
    assert relative_links(text) == ["docs/x.md", "fig.png"]


def test_every_relative_link_points_to_a_file():
    generated = generated_pages()
    broken = []
    for md in markdown_files():
        for target in relative_links(md.read_text(encoding="utf-8")):
            path = (md.parent / target).resolve()
            if not (path.exists() or path in generated):
                broken.append(f"{md.relative_to(REPO)}: {target}")
    assert not broken, "links to missing files:\n" + "\n".join(broken)


@pytest.mark.slow
def test_site_builds_without_warnings():
    """scripts/docs.sh from scratch (-E: every page read again, so no warning hides in
    an earlier build): the script fails on any warning, and none is printed."""
    env = {**os.environ, "PIP_ROOT_USER_ACTION": "ignore"}   # pip's own warning as root
    proc = subprocess.run(["bash", str(REPO / "scripts" / "docs.sh"), "-E"], cwd=REPO,
                          env=env, capture_output=True, text=True, timeout=900)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out[-4000:]
    assert "WARNING" not in out and "ERROR" not in out, out[-4000:]
    for page in ("index", "reference/cli", "reference/scene", "reference/tables",
                 "reference/config", "reference/api/scene", "explanation/benchmarks",
                 "tutorials/index"):
        assert (DOCS / "_build" / "html" / f"{page}.html").is_file(), page
