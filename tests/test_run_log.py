"""A run logs itself: an exported main.py under rps writes comat_run.npy and its metadata beside the
folder (never into it), incrementally, and comat reads them back; damaged logs give one-line errors."""

import hashlib
import json
import os
import runpy
import shutil

import numpy as np
import pytest

from comat.cli import main
from comat.runlog import (
    FLUSH_EVERY,
    LOG_FILE,
    META_FILE,
    RunLogError,
    RunLogWriter,
    bytes_per_robot_minute,
    columns,
    read_run_log,
)
from sim2real.check import run_rps


@pytest.fixture(scope="module")
def checked(tmp_path_factory):
    """A shipped COMAT policy's export, run under the installed rps (a few env steps)."""
    folder = tmp_path_factory.mktemp("runlog") / "pcp"
    assert main(["export", "--policy", "pretrained:comat-pcp", "--team", "test:3", "--out", str(folder)]) == 0
    result = run_rps(folder, max_steps=4)
    return folder, result


def test_an_exported_run_logs_what_it_saw_and_did(checked):
    folder, result = checked
    assert sorted(p.name for p in folder.iterdir()) == sorted(
        [
            "comat_schema.py",
            "deployed_loop.py",
            "main.py",
            "rps_compat.py",
            "run_log.py",
            "runtime.py",
            "submission_config.py",
            "task_logic.py",
            "task_pcp.py",
            "weights.npy",
        ]
    )  # the uploaded folder stays as exported: the log is beside it
    log = read_run_log(result["run_log"])
    config = runpy.run_path(str(folder / "submission_config.py"))["CONFIG"]
    n = len(config["types"])
    assert log.complete and log.meta["result"]["steps"] == result["steps"] == 4
    assert log.meta["types"] == config["types"] and log.meta["capabilities"] == config["capabilities"]
    assert log.meta["policy_sha256"] == hashlib.sha256((folder / "weights.npy").read_bytes()).hexdigest()
    assert log.meta["comat_version"] and log.meta["rps"] in ("legacy", "v2") and log.meta["columns"] == columns(n)
    # one row per iteration run (the last, which ends the episode, sends nothing), steps counted up
    assert log.data.shape == (4 * config["ticks_per_step"], 3 + 8 * n)
    assert (np.diff(log.data[:, 1]) == 1).all() and log.step[-1] == 3 and (np.diff(log.t) >= 0).all()
    # the policy's actions where each env step starts, -1 between
    starts = np.flatnonzero((log.actions >= 0).all(axis=1))
    assert starts.tolist() == [k * config["ticks_per_step"] for k in range(4)]
    assert ((log.actions == -1).all(axis=1)).sum() == len(log.t) - 4
    # the poses the script received begin at the start poses; what was sent obeys the wheel limit
    np.testing.assert_allclose(log.poses[0].T, np.array(config["start_poses"]), atol=1e-5)
    assert np.isfinite(log.nominal).all() and np.isfinite(log.sent).all()


def test_a_run_cut_short_returns_what_it_flushed(tmp_path):
    writer = RunLogWriter(str(tmp_path), {"task": "pcp"}, 2)
    for k in range(2 * FLUSH_EVERY + 7):
        writer.write(0.033 * k, k, k // 29, np.full((3, 2), k), np.zeros((2, 2)), np.ones((2, 2)))
    log = read_run_log(str(tmp_path))  # killed here: no finish()
    assert not log.complete and log.data.shape == (2 * FLUSH_EVERY, 19) and log.poses[-1, 0, 0] == 2 * FLUSH_EVERY - 1
    writer.finish({"steps": 4})
    assert read_run_log(str(tmp_path / LOG_FILE)).complete and len(read_run_log(str(tmp_path)).t) == 2 * FLUSH_EVERY + 7


def test_damaged_logs_give_one_line_errors(checked, tmp_path):
    source = checked[1]["run_log"]

    def copy(name):
        folder = tmp_path / name
        shutil.copytree(source, folder)
        return folder

    with pytest.raises(RunLogError, match="no such file"):
        read_run_log(str(tmp_path / "nothing"))
    cut = copy("cut")  # a download cut short: fewer bytes than the header's rows
    data = (cut / LOG_FILE).read_bytes()
    (cut / LOG_FILE).write_bytes(data[: len(data) // 2])
    with pytest.raises(RunLogError, match="not a readable .npy file"):
        read_run_log(str(cut))
    other = copy("other")  # another comat's format
    meta = json.loads(np.load(other / META_FILE).tobytes())
    np.save(other / META_FILE, np.frombuffer(json.dumps({**meta, "version": 99}).encode(), np.uint8))
    with pytest.raises(RunLogError, match="format version 99 .* this comat reads version 1"):
        read_run_log(str(other))
    garbage = copy("garbage")
    (garbage / META_FILE).write_bytes(b"not a log")
    with pytest.raises(RunLogError, match="not a comat run log's metadata"):
        read_run_log(str(garbage))
    robots = copy("robots")  # rows of another team size
    np.save(robots / META_FILE, np.frombuffer(json.dumps({**meta, "robots": meta["robots"] + 1}).encode(), np.uint8))
    with pytest.raises(RunLogError, match="expected float32 rows of"):
        read_run_log(str(robots))


def test_the_log_size_is_what_the_docs_say():
    """8 float32 per robot and iteration: 58 kB per robot-minute (docs/export.md)."""
    assert round(bytes_per_robot_minute() / 1e3) == 58


@pytest.mark.skipif(not os.environ.get("COMAT_RPS_V2"), reason="needs COMAT_RPS_V2: a checkout of the 2026 V2 rps")
def test_a_run_under_the_v2_simulator_logs_too(checked):
    """V2 drives the robots from its chargers to the start poses first: the log starts where main.py's
    loop starts, at those poses."""
    folder = checked[0]
    result = run_rps(folder, rps_path=os.environ["COMAT_RPS_V2"], max_steps=2, seed=7)
    log = read_run_log(result["run_log"])
    assert log.complete and log.meta["rps"] == "v2" and log.step[-1] == 1
    assert (log.actions[0] >= 0).all() and np.isfinite(log.poses).all()
