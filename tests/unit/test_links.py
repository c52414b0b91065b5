"""Every link in README.md and docs/ resolves: a relative file link names a file that exists, and
an ``#anchor`` names a heading of the target Markdown file under GitHub's rules for heading ids."""

import re
from collections import Counter
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
FENCE = re.compile(r"^(```|~~~)")
CODE_SPAN = re.compile(r"(`+).+?\1")
LINK = re.compile(r"!?\[(?:[^\[\]]|\[[^\[\]]*\])*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
HEADING = re.compile(r"^ {0,3}(#{1,6})\s+(.*?)(?:\s+#+)?\s*$")
HTML_ID = re.compile(r"<a\s+(?:name|id)=\"([^\"]+)\"")


def markdown_files() -> list[Path]:
    """README.md, CHANGELOG.md and every Markdown file under docs/ (the results' JSON aside)."""
    return [ROOT / "README.md", ROOT / "CHANGELOG.md", *sorted((ROOT / "docs").rglob("*.md"))]


def prose_lines(text: str):
    """(line number, line) outside fenced code blocks, with inline code spans blanked."""
    in_fence = False
    for number, line in enumerate(text.splitlines(), 1):
        if FENCE.match(line.lstrip()):
            in_fence = not in_fence
            continue
        if not in_fence:
            yield number, CODE_SPAN.sub("", line)


def github_slug(heading: str) -> str:
    """The id GitHub gives a heading: its rendered text lower-cased, punctuation dropped (letters,
    digits, ``_``, ``-`` and spaces kept), each space a hyphen."""
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", heading)  # a link: its text
    text = re.sub(r"<[^>]+>", "", text).replace("`", "")
    text = re.sub(r"(\*+|(?<!\w)_+|_+(?!\w))", "", text)  # emphasis markers
    return re.sub(r"[^\w\- ]", "", text.strip().lower()).replace(" ", "-")


def anchors(path: Path) -> set[str]:
    """Every id a reader can link to in a Markdown file: headings (repeats numbered -1, -2, ...
    as GitHub numbers them) and explicit ``<a name=...>`` / ``<a id=...>``."""
    seen: Counter = Counter()
    found = set()
    in_fence = False
    for line in path.read_text(encoding="utf-8").splitlines():
        if FENCE.match(line.lstrip()):
            in_fence = not in_fence
            continue
        if in_fence:
            continue
        found.update(HTML_ID.findall(line))
        m = HEADING.match(line)
        if m:
            slug = github_slug(m.group(2))
            found.add(slug if seen[slug] == 0 else f"{slug}-{seen[slug]}")
            seen[slug] += 1
    return found


def broken_links(path: Path) -> list[str]:
    """The links of one Markdown file that do not resolve, each as 'file:line: target (why)'."""
    out = []
    for number, line in prose_lines(path.read_text(encoding="utf-8")):
        for target in LINK.findall(line):
            if re.match(r"^[a-z][a-z0-9+.-]*:", target, re.I):  # http:, https:, mailto:
                continue
            file_part, _, anchor = target.partition("#")
            dest = (path.parent / file_part).resolve() if file_part else path
            where = f"{path.relative_to(ROOT)}:{number}: {target}"
            if not dest.exists():
                out.append(f"{where} (no such file)")
            elif anchor and dest.suffix == ".md" and anchor not in anchors(dest):
                out.append(f"{where} (no heading with that id in {dest.relative_to(ROOT)})")
    return out


@pytest.mark.parametrize("path", markdown_files(), ids=lambda p: str(p.relative_to(ROOT)))
def test_every_link_resolves(path):
    assert broken_links(path) == []


def test_a_broken_link_is_found(tmp_path, monkeypatch):
    monkeypatch.setattr(f"{__name__}.ROOT", tmp_path)
    (tmp_path / "b.md").write_text("# A heading, with `code`\n\n## A heading, with code\n")
    page = tmp_path / "a.md"
    page.write_text(
        "[ok](b.md#a-heading-with-code) [repeat](b.md#a-heading-with-code-1) [self](#top)\n"
        "# Top\n[gone](c.md) [no anchor](b.md#nowhere) `[in code](d.md)`\n```\n[fenced](e.md)\n```\n"
    )
    assert [b.split(": ", 1)[1] for b in broken_links(page)] == [
        "c.md (no such file)",
        "b.md#nowhere (no heading with that id in b.md)",
    ]


def test_github_slugs():
    assert github_slug("The estimator in the loop (`quadest reproduce afckf --in-loop`)") == (
        "the-estimator-in-the-loop-quadest-reproduce-afckf---in-loop"
    )
    assert github_slug("The loss's transient, with the rotors' inertia") == (
        "the-losss-transient-with-the-rotors-inertia"
    )
    assert github_slug("`drain_margin`, *drain_priority*") == "drain_margin-drain_priority"
