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


@pytest.mark.parametrize(
    "kind, expected",
    [
        ("missing", "is not an exported submission: missing"),
        ("file", "is not an exported submission: missing"),
        ("empty", "is not an exported submission: missing"),
        ("syntax", "is not an exported submission config (line 1)"),
        ("not-a-dict", "CONFIG must be a dict, got list"),
        ("no-config", "has no CONFIG literal"),
    ],
)
def test_check_refuses_what_is_not_a_submission(tmp_path, capsys, kind, expected):
    path = _folder(tmp_path, kind)
    assert main(["export", "--check", str(path)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    last = err.strip().splitlines()[-1]
    assert last.startswith("comat export: error:") and expected in last and str(path) in last


def test_a_folder_whose_runtime_reads_the_schema_needs_it_and_older_folders_do_not(tmp_path, capsys):
    """``runtime.py`` reads COMAT's weight description from ``comat_schema.py`` beside it; a folder
    exported before that has a runtime that describes the arrays itself and no such file."""
    from sim2real.check import check_submission
    from sim2real.export import SHIPPED_FILES

    path = tmp_path / "sub"
    path.mkdir()
    for name in SHIPPED_FILES:
        if name != "comat_schema.py":
            (path / name).write_text("")
    (path / "submission_config.py").write_text("CONFIG = {'policy': 'comat', 'filter': {'filter': 'robotarium'}}")
    (path / "runtime.py").write_text("from comat_schema import weight_shapes\n")
    assert main(["export", "--check", str(path)]) == 2
    assert "missing ['comat_schema.py']" in capsys.readouterr().err
    (path / "runtime.py").write_text("def expected_shapes(config): ...\n")  # an older runtime
    with pytest.raises(ValueError, match="--drive must be one of"):  # past the file check
        check_submission(path, drive="nowhere")
