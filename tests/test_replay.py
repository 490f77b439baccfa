"""comat replay: a run's log (here a run under rps standing in for the Robotarium) beside its twin in
MuJoCo, as a Rerun file and a gap table; a folder that is not the run's, and a run cut short."""

import json
import shutil
import subprocess
import sys
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest

from comat.cli import main
from comat.runlog import LOG_FILE, META_FILE, read_run_log
from sim2real.check import run_rps


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    root = tmp_path_factory.mktemp("replay")
    folder = root / "pcp"
    assert main(["export", "--policy", "pretrained:comat-pcp", "--team", "test:3", "--out", str(folder)]) == 0
    return folder, Path(run_rps(folder, max_steps=6)["run_log"])


def test_replay_writes_the_run_beside_its_twin(run, capsys):
    folder, log = run
    out, video = log.parent / "r.rrd", log.parent / "r.gif"
    argv = ["replay", str(log), "--export", str(folder), "--out", str(out), "--video", str(video), "--open-loop"]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "| steps | 6 |" in printed and "position divergence mean (m)" in printed
    rerun = shutil.which("rerun") or str(Path(sys.executable).parent / "rerun")
    assert subprocess.run([rerun, "rrd", "verify", str(out)], capture_output=True, check=False).returncode == 0
    rows = (log.parent / "r_gap.csv").read_text().splitlines()
    assert rows[0] == "quantity,real,twin,gap" and rows[1].startswith("steps,6,")
    divergence = [float(r.split(",")[-1]) for r in rows if r.startswith("position divergence")]
    assert len(divergence) == 3 and all(np.isfinite(divergence)) and divergence[0] <= divergence[2]
    # the logged commands played open-loop to MuJoCo's unicycle robots track rps's kinematic ones closely
    played = {r.split(",")[0]: float(r.split(",")[-1]) for r in rows if r.startswith("open-loop divergence")}
    assert set(played) == {"open-loop divergence mean (m)", "open-loop divergence max (m)"}
    assert played["open-loop divergence max (m)"] < 0.01  # 2 mm here over 6 steps
    assert iio.imread(video, index=None).shape[0] == 6  # a frame per compared env step


def test_a_folder_that_is_not_the_runs_is_refused(run, tmp_path, capsys):
    log = run[1]
    other = tmp_path / "other"
    assert main(["export", "--policy", "pretrained:comat-pcp", "--team", "test:4", "--out", str(other)]) == 0
    capsys.readouterr()
    assert main(["replay", str(log), "--export", str(other), "--out", str(tmp_path / "x.rrd")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("comat replay: error: --export") and "but the run logged" in err
    assert not (tmp_path / "x.rrd").exists()  # nothing half-written


def test_a_run_cut_short_is_compared_as_far_as_it_logged(run, tmp_path, capsys):
    folder, log = run
    cut = tmp_path / "cut"
    shutil.copytree(log, cut)
    full = read_run_log(str(log))
    rows = 2 * full.meta["ticks_per_step"] + 5  # killed during its third env step
    np.save(cut / LOG_FILE, full.data[:rows])
    meta = {k: v for k, v in full.meta.items() if k != "result"}
    np.save(cut / META_FILE, np.frombuffer(json.dumps(meta).encode(), np.uint8))
    assert main(["replay", str(cut), "--export", str(folder)]) == 0
    printed = capsys.readouterr().out
    assert "cut short" in printed and "| steps |  |" in printed  # no result: the twin's alone
    assert "3 env steps" in printed


def test_the_divergence_a_known_profile_adds_and_the_twin_at_that_profile_removes(run, tmp_path):
    """A stand-in run under a known layer (3 ticks of pose delay, the robots moved by MuJoCo's
    unicycle tier): the twin in the ideal world diverges from it, the twin at the run's profile does
    not (the same poses to the log's float32 precision over the steps both take the same actions)."""
    from comat.eval.replay import replay

    folder = run[0]
    profile = tmp_path / "late.yaml"
    profile.write_text("reality:\n  level: 'off'\n  pose_delay_ticks: 3\n")
    log = run_rps(folder, max_steps=8, reality=str(profile), seed=0, drive="unicycle")["run_log"]

    def divergence(reality):
        rows = replay(log, str(folder), str(tmp_path / f"{reality.split('/')[-1]}.rrd"), reality=reality)["rows"]
        return next(r["gap"] for r in rows if r["quantity"] == "position divergence mean (m)")

    ideal, late = divergence("off"), divergence(str(profile))
    assert late < 1e-4 and ideal > 0.005  # 0.1 mm: the log's float32 poses; the delay alone is centimetres
