"""The documentation stands on the repository alone: every Markdown link and image in README.md,
docs/*.md and results/**/README.md is a public URL or a file inside the repository, no page
names a file outside it, and every § reference of the reality layer names a section of
docs/reality-sources.md (issue 51)."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

OUTSIDE = ("../shared", "shared/reference", "shared/paper")
"""Text that names the project's notes outside the repository."""

_FENCE = re.compile(r"^(\s*)(`{3,}|~{3,}).*?^\1\2[^\n]*$", re.MULTILINE | re.DOTALL)
_CODE_SPAN = re.compile(r"(`+)(?:(?!\1).)+?\1", re.DOTALL)
# [text](target "title") and ![alt](target); the text may hold one level of brackets (images in links)
_INLINE = re.compile(r"!?\[(?:[^\[\]]|\[[^\[\]]*\])*\]\(\s*<?([^)\s>]*)>?(?:\s+[\"'(][^)]*)?\)")
_REFERENCE = re.compile(r"^\s{0,3}\[[^\]]+\]:\s*<?(\S+?)>?(?:\s+.*)?$", re.MULTILINE)
_HTML = re.compile(r"<(?:a|img)\s[^>]*?(?:href|src)\s*=\s*[\"']([^\"']+)[\"']", re.IGNORECASE)


def pages() -> list[Path]:
    """The Markdown pages a reader of the repository is pointed to."""
    return [
        ROOT / "README.md",
        *sorted((ROOT / "docs").glob("*.md")),
        *sorted((ROOT / "results").rglob("README.md")),
    ]


def prose(text: str) -> str:
    """The page without fenced code blocks and code spans (paths there are commands, not links)."""
    return _CODE_SPAN.sub("", _FENCE.sub("", text))


def link_targets(text: str) -> list[str]:
    """Every link and image target of a page's prose: inline, reference definitions, HTML."""
    body = prose(text)
    return [m.group(1) for rx in (_INLINE, _REFERENCE, _HTML) for m in rx.finditer(body)]


def bad_target(page: Path, target: str) -> str | None:
    """Why a link target leaves the repository (None if it is fine)."""
    if re.match(r"https?://", target) or target.startswith(("mailto:", "#")) or not target:
        return None
    if re.match(r"[a-z][a-z0-9+.-]*:", target, re.IGNORECASE):
        return "a non-public URL scheme"
    path = target.split("#", 1)[0].split("?", 1)[0]
    if path.startswith("/"):
        return "an absolute path"
    resolved = (page.parent / path).resolve()
    if not resolved.is_relative_to(ROOT):
        return "a path outside the repository"
    if not resolved.exists():
        return "a path that does not exist"
    return None


def problems(page: Path) -> list[str]:
    text = page.read_text(encoding="utf-8")
    rel = page.relative_to(ROOT)
    out = [f"{rel}: link to {t!r} is {why}" for t in link_targets(text) if (why := bad_target(page, t))]
    out += [f"{rel}: mentions {s!r}" for s in OUTSIDE if s in text]
    return out


def test_every_link_is_public_or_inside_the_repository():
    found = [p for page in pages() for p in problems(page)]
    assert not found, "\n".join(found)


def test_the_check_catches_a_link_outside():
    page = ROOT / "docs" / "index.md"
    assert bad_target(page, "../shared/foo.md") == "a path that does not exist"
    assert bad_target(page, "../../shared/paper/x.md") == "a path outside the repository"
    assert bad_target(page, "missing.md#a") == "a path that does not exist"
    assert bad_target(page, "reality.md#safety-under-the-layer") is None
    assert bad_target(page, "https://github.com/robotarium/GTernal") is None
    text = "See [x](../shared/foo.md), ![i](/etc/x.png), `[y](../shared/in-code.md)` and\n```\n[z](../z.md)\n```\n"
    assert link_targets(text) == ["../shared/foo.md", "/etc/x.png"]


def _sections(text: str) -> set[str]:
    return set(re.findall(r"^#{2,3} .*\{#(s[0-9-]+)\}\s*$", text, re.MULTILINE))


def _refs(text: str) -> set[str]:
    """The section anchors that "§1.1-1.2", "§6 #3", "§2.3" name."""
    out = set()
    for m in re.finditer(r"§(\d+)(?:\.(\d+))?(?:-(\d+)\.(\d+))?(?: #(\d+))?", text):
        major, minor, major2, minor2, item = m.groups()
        out.add(f"s{major}" + (f"-{minor}" if minor else "") + (f"-{item}" if item else ""))
        if major2:
            out.add(f"s{major2}-{minor2}")
    return out


def test_every_reality_section_reference_names_a_section_of_the_sources_page():
    """config.py's sources and docstrings and docs/reality.md cite § numbers: each is a heading of
    docs/reality-sources.md, and every link into it lands on one."""
    sections = _sections((ROOT / "docs" / "reality-sources.md").read_text(encoding="utf-8"))
    cited = _refs((ROOT / "comat" / "reality" / "config.py").read_text(encoding="utf-8"))
    reality = (ROOT / "docs" / "reality.md").read_text(encoding="utf-8")
    cited |= _refs(reality)
    cited |= set(re.findall(r"reality-sources\.md#(s[0-9-]+)", reality))
    assert {"s1-1", "s6-3", "s6-13"} <= cited
    assert cited <= sections, f"§ references without a section: {sorted(cited - sections)}"
