"""The user and maintainer docs hold together: every relative link in README.md and
docs/*.md names an existing file, every `#anchor` names a heading of its target (GitHub's
slugs), README.md stays short, and no doc is a "Stop N" diary."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README_MAX_LINES = 300
LINK = re.compile(r"!?\[(?:[^\[\]]|\[[^\]]*\])*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
CODE_SPAN = re.compile(r"(`+)(?:(?!\1).)+?\1")
SCHEME = re.compile(r"^[a-zA-Z][a-zA-Z0-9+.-]*:")
STOP_N = re.compile(r"\bstop\s+\d+", re.IGNORECASE)


def doc_files(root: Path) -> list[Path]:
    """README.md and every docs/*.md under root."""
    return [root / "README.md", *sorted((root / "docs").glob("*.md"))]


def prose_lines(text: str) -> list[tuple[int, str]]:
    """(line number, line) outside fenced and indented code blocks, code spans blanked."""
    out: list[tuple[int, str]] = []
    fence: str | None = None
    previous_blank, in_indented = True, False
    for number, line in enumerate(text.splitlines(), 1):
        stripped = line.lstrip()
        marker = re.match(r"(`{3,}|~{3,})", stripped)
        if fence is not None:
            if marker and marker.group(1)[0] == fence[0] and len(marker.group(1)) >= len(fence):
                fence = None
            previous_blank = False
            continue
        if marker:
            fence = marker.group(1)
            continue
        blank = not line.strip()
        indented = line.startswith(("    ", "\t")) and not blank
        in_indented = indented and (previous_blank or in_indented)
        if not in_indented:
            out.append((number, CODE_SPAN.sub("", line)))
        if not blank:
            previous_blank = False
        else:
            previous_blank = True
    return out


def slug(heading: str) -> str:
    """GitHub's anchor of a heading: link text kept, lowercase, punctuation dropped (letters,
    digits, spaces, hyphens and underscores stay), spaces to hyphens."""
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", heading.strip())
    text = re.sub(r"[^\w\- ]", "", text.lower())
    return text.replace(" ", "-")


def anchors(path: Path) -> set[str]:
    """Every heading anchor of a markdown file, duplicates numbered as GitHub does."""
    seen: dict[str, int] = {}
    out: set[str] = set()
    raw = path.read_text(encoding="utf-8")
    # headings need their code spans' text (GitHub keeps it), so read them from the raw lines
    lines = raw.splitlines()
    for number, _ in prose_lines(raw):
        match = re.match(r" {0,3}(#{1,6})\s+(.*?)\s*#*\s*$", lines[number - 1])
        if not match:
            continue
        base = slug(match.group(2))
        n = seen.get(base, 0)
        seen[base] = n + 1
        out.add(base if n == 0 else f"{base}-{n}")
    return out


def links(path: Path) -> list[tuple[int, str]]:
    """(line number, target) of every inline link and image outside code."""
    return [(number, m.group(1)) for number, line in prose_lines(path.read_text(encoding="utf-8"))
            for m in LINK.finditer(line)]


def link_problems(root: Path) -> list[str]:
    """One message per relative link whose file or anchor does not exist."""
    problems = []
    for doc in doc_files(root):
        for number, target in links(doc):
            if SCHEME.match(target):
                continue                      # http(s), mailto: not checked here
            file_part, _, anchor = target.partition("#")
            dest = doc if not file_part else (doc.parent / file_part).resolve()
            where = f"{doc.relative_to(root)}:{number}: {target}"
            if not dest.exists():
                problems.append(f"{where}: no such file")
            elif anchor and dest.suffix == ".md" and anchor not in anchors(dest):
                problems.append(f"{where}: no heading #{anchor} in {dest.name}")
            elif anchor and dest.suffix != ".md":
                problems.append(f"{where}: an anchor into a file that is not markdown")
    return problems


def diary_problems(root: Path) -> list[str]:
    """One message per 'Stop N' in the docs (history belongs in commit messages)."""
    return [f"{doc.relative_to(root)}:{number}: {m.group(0)!r}"
            for doc in doc_files(root)
            for number, line in enumerate(doc.read_text(encoding="utf-8").splitlines(), 1)
            for m in STOP_N.finditer(line)]


def readme_lines(root: Path) -> int:
    return len((root / "README.md").read_text(encoding="utf-8").splitlines())


def test_every_relative_link_and_anchor_resolves():
    assert link_problems(ROOT) == []


def test_readme_is_short():
    assert readme_lines(ROOT) <= README_MAX_LINES


def test_no_stop_diaries_in_the_docs():
    assert diary_problems(ROOT) == []


def test_docs_are_linked_from_the_readme():
    linked = {(ROOT / t.partition("#")[0]).resolve() for _, t in links(ROOT / "README.md")
              if not SCHEME.match(t) and t.partition("#")[0]}
    missing = [p.name for p in sorted((ROOT / "docs").glob("*.md")) if p.resolve() not in linked]
    assert missing == []


@pytest.mark.parametrize("heading, expected", [
    ("Synthetic scenes (`vtrack synth`)", "synthetic-scenes-vtrack-synth"),
    ("A calibrated example, end to end", "a-calibrated-example-end-to-end"),
    ("Iterated filters: iekf and iplf", "iterated-filters-iekf-and-iplf"),
    ("The scene suite, seeds 0-2", "the-scene-suite-seeds-0-2"),
    ("[docs/RESULTS.md](docs/RESULTS.md) and more", "docsresultsmd-and-more"),
])
def test_slug_follows_github(heading, expected):
    assert slug(heading) == expected


def test_checks_catch_broken_docs(tmp_path):
    """The checks fail on a missing file, a missing heading, a diary and a long README; links
    in code are not links."""
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "A.md").write_text(
        "# A page\n\n## Same\n\n## Same\n\nBack to [the top](#a-page), [second](#same-1).\n"
        "\n    [in code](missing-in-code.md)\n\nAnd `[span](missing-span.md)`.\n",
        encoding="utf-8")
    (tmp_path / "README.md").write_text(
        "# R\n\nSee [A](docs/A.md#same), [gone](docs/B.md), [bad anchor](docs/A.md#nothing),\n"
        "[self](#r), ![pic](docs/img/none.png) and [web](https://example.org/x#y).\n"
        "Stop 41 found this.\n" + "line\n" * README_MAX_LINES, encoding="utf-8")
    problems = link_problems(tmp_path)
    assert len(problems) == 3, problems
    assert any("docs/B.md: no such file" in p for p in problems)
    assert any("#nothing" in p and "no heading" in p for p in problems)
    assert any("none.png: no such file" in p for p in problems)
    assert diary_problems(tmp_path) == ["README.md:5: 'Stop 41'"]
    assert readme_lines(tmp_path) > README_MAX_LINES
