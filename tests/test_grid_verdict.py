"""The grid's verdict is generated, not typed (issue 50): the block of results/README.md between its
verdict markers is the last section of ``results/grid_v3/analyze.py``'s output on the kept runs, and
``grid_v3/tests.md`` is that output. Its wording is exact (issue 68): each secondary read by the
plan's unadjusted rule and after Holm, the six COMAT − MAPPO-20 contrasts both ways, where COMAT is
level with MAT by team size, and the report's Welch table with a Holm column."""

from __future__ import annotations

import contextlib
import importlib.util
import io
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
GRID = ROOT / "results" / "grid_v3"


@pytest.fixture(scope="module")
def printed() -> str:
    spec = importlib.util.spec_from_file_location("grid_v3_analyze", GRID / "analyze.py")
    analyze = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(analyze)
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        analyze.main()
    return out.getvalue()


def _bullets(printed: str) -> dict[str, str]:
    """The verdict's bullets by their bold heading."""
    section = printed[printed.index("## The verdict in numbers") :]
    return {m[1]: m[0] for m in re.finditer(r"^\* \*\*(.+?)\*\*.*$", section, flags=re.MULTILINE)}


def test_the_readme_verdict_and_tests_md_are_what_analyze_prints(printed):
    assert printed == (GRID / "tests.md").read_text()
    section = printed[printed.index("## The verdict in numbers") :].split("\n", 2)[2].strip("\n")
    readme = (ROOT / "results" / "README.md").read_text()
    block = readme[readme.index("<!-- verdict:begin -->") : readme.index("<!-- verdict:end -->")]
    assert block.split("\n", 1)[1].strip("\n") == section
    # the corrections of issue 50: the gap and the PCP U_cap difference are quoted with their Holm p
    assert "Holm over the 12 gap tests" in section and "Holm over the 20 secondary tests" in section
    assert "U_size -1.9 [-3.3, -0.5] (p = 0.010, Holm 0.124" in section
    assert "PCP U_cap -2.0 [-3.9, -0.1] (p = 0.044, Holm 0.704" in section


def test_the_wording_is_exact(printed):
    bullets = _bullets(printed)
    section = "\n".join(bullets.values())
    # the 1 M result is the only one in the paper's direction against MAT, not overall
    assert "The only result in the paper's direction *against MAT*" in section
    assert "points the paper's way" not in section
    # one bullet quotes all six COMAT − MAPPO-20 contrasts, both ways, each read both ways
    mappo = next(text for head, text in bullets.items() if "MAPPO-20, both ways" in head)
    for contrast in (
        "PCP U_size +6.1 [+4.8, +7.5] (p < 0.001, Holm < 0.001",
        "PCP U_cap +12.3 [+7.3, +17.2] (p = 0.002, Holm 0.040)",
        "HMT U_scale -4.3 [-8.0, -0.5] (p = 0.030, Holm 0.541",
        "HMT U_size -1.4 [-3.4, +0.6] (p = 0.146, Holm 1.000)",
        "HMT U_cap +3.3 [-1.3, +8.0] (p = 0.136, Holm 1.000)",
        "PCP U_scale -0.9 [-3.3, +1.6] (p = 0.399, Holm 1.000)",
    ):
        assert contrast in mappo, contrast
    assert "COMAT better by the plan's unadjusted rule and after Holm" in mappo
    assert "COMAT worse by the plan's unadjusted rule, no difference of 10 points or more after Holm" in mappo
    # every secondary bullet reads its tests both ways
    for head, text in bullets.items():
        if head.startswith("Secondary"):
            assert "by the plan's unadjusted rule" in text and "after Holm" in text, head
    cap = next(text for head, text in bullets.items() if head.startswith("Secondary — capability"))
    assert "COMAT worse by the plan's unadjusted rule, no difference of 10 points or more after Holm" in cap
    timing = next(text for head, text in bullets.items() if head.startswith("Secondary — timing"))
    assert "Of all 20 secondary tests, 5 separate by the plan's unadjusted rule" in timing
    assert "and 2 after Holm (PCP U_size against MAPPO-20 and PCP U_cap against MAPPO-20)" in timing
    # level with MAT from 4 to 14 robots, not below (2 robots: -6.3 on U_size), lower above
    size = next(text for head, text in bullets.items() if head.startswith("Descriptive — by team size"))
    assert "Level with MAT from 4 to 14 robots" in size and "not below: at 2 robots -6.3 [-17.5, +4.9]" in size
    assert "lower at 16–20 (-3.2, -4.8 and -5.9 points; 90.9 vs 96.8 % at 20)" in size
    assert "up to 14 robots" not in (ROOT / "results" / "README.md").read_text()


def test_the_by_size_sentence_follows_its_table(printed):
    """The sentence's sizes are the table's: every size from 4 to 14 within ±2 points, 2 and 16-20 not."""
    table = printed[printed.index("## By team size") : printed.index("## Exploratory")]
    row = re.compile(r"^\| (\d+) \| \d+ \| [^|]+\| [^|]+\| ([-+]\d+\.\d)", re.MULTILINE)
    diffs = {int(m[1]): float(m[2]) for m in row.finditer(table)}
    assert sorted(diffs) == [2, 4, 6, 8, 10, 12, 14, 16, 18, 20]
    assert all(abs(diffs[n]) < 2 for n in range(4, 15, 2))
    assert abs(diffs[2]) >= 2 and all(diffs[n] <= -2 for n in (16, 18, 20))


def test_generalization_md_has_a_holm_column():
    """The report's Welch table: every tested row with its Holm p, and the caption's count of the
    'higher / lower' verdicts that keep p < 0.05 after Holm equals the rows'."""
    md = (GRID / "generalization.md").read_text()
    assert "| t | df | p | Holm p | Welch verdict (unadjusted p) |" in md
    rows = [ln.split(" | ") for ln in md.splitlines() if re.match(r"^\| (PCP|HMT) \| U_", ln)]
    labelled = [r for r in rows if r[11].startswith(("COMAT higher", "COMAT lower"))]
    kept = [r for r in labelled if r[10] == "< 0.001" or float(r[10]) < 0.05]
    assert all(r[10] != "—" for r in labelled) and len(labelled) == 33
    assert f"{len(kept)} of the {len(labelled)} 'higher / lower' verdicts keep p < 0.05 after it" in md
    hmt_scale_mappo = next(r for r in rows if r[:4] == ["| HMT", "U_scale", "progress", "MAPPO"])
    assert hmt_scale_mappo[9] == "0.030" and float(hmt_scale_mappo[10]) > 0.05  # separated unadjusted only
