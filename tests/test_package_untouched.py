"""Nothing writes into the installed package: commands given a shipped policy (``pretrained:NAME``)
write beside the user, under ``runs/pretrained-NAME``, one folder per shipped policy."""

from pathlib import Path

import comat
from comat.cli import main

PACKAGE = Path(comat.__file__).parent
TEAM = """robots:
  - {type: sensing, capabilities: [0.45, 0.0]}
  - {type: capture, capabilities: [0.0, 0.25]}
"""


def _files(root: Path) -> dict[str, tuple[int, int]]:
    """Every file under ``root`` but bytecode caches, with its size and modification time."""
    return {
        str(p.relative_to(root)): (p.stat().st_size, p.stat().st_mtime_ns)
        for p in root.rglob("*")
        if p.is_file() and "__pycache__" not in p.parts
    }


def test_commands_on_shipped_policies_never_write_into_the_package(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "team.yaml").write_text(TEAM)
    before = _files(PACKAGE)
    for name in ("comat-pcp", "mat-pcp"):
        argv = ["eval", "--policy", f"pretrained:{name}", "--teams", "team.yaml", "--episodes", "1", "--no-references"]
        assert main(argv) == 0, capsys.readouterr().err
        assert (tmp_path / "runs" / f"pretrained-{name}" / "evaluation_unicycle.json").is_file()
    assert main(["policy", "pretrained:comat-pcp"]) == 0
    capsys.readouterr()
    assert main(["rollout", "--policy", "pretrained:comat-pcp", "--team", "team.yaml", "--out", "x.rrd"]) == 0
    assert "policy pretrained:comat-pcp (comat)," in capsys.readouterr().err  # named, not "policy comat policy"
    assert _files(PACKAGE) == before
