"""The grid's verdict is generated, not typed (issue 50): the block of results/README.md between its
verdict markers is the last section of ``results/grid_v3/analyze.py``'s output on the kept runs, and
``grid_v3/tests.md`` is that output."""

from __future__ import annotations

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_the_readme_verdict_and_tests_md_are_what_analyze_prints(capsys):
    spec = importlib.util.spec_from_file_location("grid_v3_analyze", ROOT / "results" / "grid_v3" / "analyze.py")
    analyze = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(analyze)
    analyze.main()
    printed = capsys.readouterr().out
    assert printed == (ROOT / "results" / "grid_v3" / "tests.md").read_text()
    section = printed[printed.index("## The verdict in numbers") :].split("\n", 2)[2].strip("\n")
    readme = (ROOT / "results" / "README.md").read_text()
    block = readme[readme.index("<!-- verdict:begin -->") : readme.index("<!-- verdict:end -->")]
    assert block.split("\n", 1)[1].strip("\n") == section
    # the corrections of issue 50: the gap and the PCP U_cap difference are quoted with their Holm p
    assert "Holm over the 12 gap tests 0.124" in section and "Holm over the 20 secondary tests 0.704" in section
