"""The project's documentation stays true to the code: every test it names exists, every link
between its files (and every anchor) resolves, the topic table is the code's, nothing cites a
document outside the repository, and the README is short and opens with its two commands."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

from predictive_drive.interface import TOPICS

pytestmark = pytest.mark.core

ROOT = Path(__file__).resolve().parents[1]
DOCS = sorted((ROOT / "docs").glob("*.md"))
PAGES = [ROOT / "README.md", *DOCS]


def test_the_docs_are_there():
    names = {p.name for p in DOCS}
    assert {"physics.md", "ros.md", "recordings.md", "reproduction.md", "performance.md",
            "architecture.md"} <= names  # fmt: skip


def _tests_defined() -> set[str]:
    out = set()
    for f in (ROOT / "test").glob("test_*.py"):
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.FunctionDef) and node.name.startswith("test_"):
                out.add(node.name)
    return out


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_every_test_a_page_names_exists(page):
    named = set(re.findall(r"\btest_[a-z0-9_]+\b", page.read_text()))
    files = {p.stem for p in (ROOT / "test").glob("test_*.py")}
    missing = sorted(n for n in named - _tests_defined() if n not in files)
    assert not missing, f"{page.name} names tests that do not exist: {missing}"


def anchor(heading: str) -> str:
    """GitHub's anchor of a Markdown heading."""
    a = heading.strip().lower()
    a = re.sub(r"[^\w\- ]", "", a)
    return a.replace(" ", "-")


def _anchors(page: Path) -> set[str]:
    return {anchor(h) for h in re.findall(r"^#+ (.+)$", page.read_text(), re.MULTILINE)}


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_every_link_and_anchor_resolves(page):
    text = page.read_text()
    bad = []
    for target in re.findall(r"\]\(([^)]+)\)", text):
        if re.match(r"[a-z]+://", target):
            continue
        path, _, frag = target.partition("#")
        dest = (page.parent / path).resolve() if path else page
        if not dest.exists():
            bad.append(f"{target}: no file {dest}")
        elif frag and dest.suffix == ".md" and frag not in _anchors(dest):
            bad.append(f"{target}: no heading with anchor #{frag} in {dest.name}")
    assert not bad, bad


#: a path in a page's text: relative (``../x``, ``./x``) or absolute on a machine
PATH_IN_TEXT = re.compile(
    r"(?<![\w.~/-])((?:\.\.?/)+[\w./-]+|/(?:work|home|root|tmp|Users)/[\w./-]*)"
)


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_no_page_points_outside_the_repository(page):
    """What a page names is in the repository: no relative path that climbs out of it or names
    nothing in it (a tool beside the developers' checkout: ../shared/...), no absolute path of
    someone's machine (a ROS install's /opt/ros/... is the user's own and allowed)."""
    bad = []
    for path in PATH_IN_TEXT.findall(page.read_text()):
        if path.startswith("/"):
            bad.append(path)
            continue
        # read from the page's folder or from the checkout's root, as a reader might
        places = [(base / path).resolve() for base in (page.parent, ROOT)]
        if not any(p.is_relative_to(ROOT) and p.exists() for p in places):
            bad.append(path)
    assert not bad, f"{page.name} points outside the repository: {bad}"


def test_code_and_tests_cite_docs_that_exist():
    """Every docs/ file and #anchor cited in src/, test/ and the scenario files resolves;
    nothing cites the steering documents outside the repository, nor a README section (the
    scenario files sent users to a README section 'Scenario assumptions' that did not exist)."""
    bad = []
    files = [*ROOT.glob("src/**/*.py"), *ROOT.glob("src/**/*.json"), *ROOT.glob("test/*.py")]
    files += sorted(ROOT.glob("config/*.yaml"))
    for f in files:
        text = f.read_text()
        if re.search(r"README\W+\"", text):
            bad.append(f"{f.name}: cites a README section (the docs hold what a user needs)")
        # the outside design documents (the bracketed letters keep this line from citing them)
        if re.search(r"[S]PEC §|[s]hared/([S]PEC|[A]RCHITECTURE|[S]TYLE)", text):
            bad.append(f"{f.name}: cites a document outside the repository")
        for doc, frag in re.findall(r"docs/([a-z_]+\.md)(?:#([a-z0-9\-]+))?", text):
            dest = ROOT / "docs" / doc
            if not dest.exists():
                bad.append(f"{f.name}: docs/{doc} does not exist")
            elif frag and frag not in _anchors(dest):
                bad.append(f"{f.name}: docs/{doc}#{frag}: no such heading")
    assert not bad, bad


def test_the_topic_table_is_the_codes():
    """docs/ros.md's table: every topic of the interface, with its type and, for the labelled
    arrays, exactly the fields the code sends, in order."""
    text = (ROOT / "docs" / "ros.md").read_text().split("## Topics", 1)[1].split("\n## ", 1)[0]
    rows = {
        m.group(1): m.group(0) for m in re.finditer(r"^\| `(/[^`]+)` \|.*$", text, re.MULTILINE)
    }
    assert set(rows) == {t.name for t in TOPICS.values()}
    for t in TOPICS.values():
        row = rows[t.name]
        assert t.type.replace("/msg/", "/") in row, (t.name, t.type)
        if t.fields:
            listed = ",".join(re.findall(r"`([^`/]+)`", row.split("|")[5]))
            listed = listed.replace(",,", ",")
            assert listed.split(",") == list(t.fields), t.name


def test_the_readme_is_short_and_opens_with_its_two_commands():
    lines = (ROOT / "README.md").read_text().splitlines()
    assert len(lines) <= 150, len(lines)
    head = "\n".join(lines[:8])
    assert "make run" in head and "make test" in head
    makefile = (ROOT / "Makefile").read_text()
    assert re.search(r"^run: ", makefile, re.M) and re.search(r"^test: ", makefile, re.M)
    assert "make test" in (ROOT / ".ci" / "run").read_text()


def test_the_contract_says_how_a_node_ends_what_t_holds_and_which_python_runs_it():
    """docs/ros.md's contract for a controller of one's own keeps what the launcher and the
    plant hold a node to: the last state is not answered, the publisher's messages acknowledged
    before exiting, ``t`` copied from the state, and the venv's interpreter for the commands."""
    text = " ".join((ROOT / "docs" / "ros.md").read_text().split())
    for said in (
        "it is not answered",
        "`Publisher.wait_for_all_acked()`",
        "its `t` the `t` of",
        "A command for another step or with another `t`",
        ".venv/bin/python examples/dtc_im/dtc_im/dtc_node.py",
    ):
        assert said in text, said
