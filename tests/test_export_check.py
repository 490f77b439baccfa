"""``comat export --check`` on folders that are not (intact) exported submissions: exit 2 and one
line naming the folder or file and what is wrong, never a traceback, before anything runs."""

import pytest

from comat.cli import main


def _folder(tmp_path, kind):
    path = tmp_path / kind
    if kind == "file":
        path.write_text("not a folder")
    elif kind != "missing":
        path.mkdir()
        if kind in ("syntax", "not-a-dict", "no-config"):
            for name in ("main.py", "rps_compat.py", "task_logic.py", "runtime.py", "weights.npy"):
                (path / name).write_text("")
            text = {"syntax": "CONFIG = {'task': (", "not-a-dict": "CONFIG = [1, 2]", "no-config": "X = 1"}[kind]
            (path / "submission_config.py").write_text(text)
    return path


@pytest.mark.parametrize("kind, expected", [
    ("missing", "is not an exported submission: missing"),
    ("file", "is not an exported submission: missing"),
    ("empty", "is not an exported submission: missing"),
    ("syntax", "is not an exported submission config (line 1)"),
    ("not-a-dict", "CONFIG must be a dict, got list"),
    ("no-config", "has no CONFIG literal"),
])
def test_check_refuses_what_is_not_a_submission(tmp_path, capsys, kind, expected):
    path = _folder(tmp_path, kind)
    assert main(["export", "--check", str(path)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    last = err.strip().splitlines()[-1]
    assert last.startswith("comat export: error:") and expected in last and str(path) in last
