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
    from comat.eval import replay_log as replay

    folder = run[0]
    profile = tmp_path / "late.yaml"
    profile.write_text("reality:\n  level: 'off'\n  pose_delay_ticks: 3\n")
    log = run_rps(folder, max_steps=8, reality=str(profile), seed=0, drive="unicycle")["run_log"]

    def divergence(reality):
        rows = replay(log, str(folder), str(tmp_path / f"{reality.split('/')[-1]}.rrd"), reality=reality)["rows"]
        return next(r["gap"] for r in rows if r["quantity"] == "position divergence mean (m)")

    ideal, late = divergence("off"), divergence(str(profile))
    assert late < 1e-4 and ideal > 0.005  # 0.1 mm: the log's float32 poses; the delay alone is centimetres


def test_the_twin_starts_where_the_run_logged_its_first_poses(run):
    """Under a layer with a start error, the twin starts at the logged first poses, not at the requested
    ones plus its own start error; without them it keeps the requested poses' error."""
    from sim2real.check import mujoco_twin

    folder, log = run
    logged = read_run_log(str(log)).poses[0].astype(float) + [0.01, -0.02, 0.1]  # any valid poses
    twin = mujoco_twin(folder, tier="unicycle", reality="nominal", start_poses=logged, max_steps=1)
    assert np.allclose(twin["poses"][0], logged, atol=1e-9) and len(twin["actions"]) == 1
    requested = np.array(read_run_log(str(log)).meta["start_poses"]).T
    own = mujoco_twin(folder, tier="unicycle", reality="nominal", max_steps=1)["poses"][0]
    assert np.hypot(*(own[:, :2] - requested[:, :2]).T).max() > 0.005  # nominal's start error, up to 5 cm


def test_the_envelope_baseline_and_k_step_tables(run, tmp_path, capsys):
    """--envelope 20 under nominal (a run of 2 env steps: 20 short twins): the real outcome's
    percentile among 20 twins per task metric, the sim-to-sim baseline with the real divergence's
    percentile, and the k-step CSV (every profile, horizon and robot, then all)."""
    folder = tmp_path / "pcp"
    shutil.copytree(run[0], folder)
    log = Path(run_rps(folder, max_steps=2)["run_log"])
    out = log.parent / "env.rrd"
    argv = ["replay", str(log), "--export", str(folder), "--out", str(out), "--reality", "nominal"]
    assert main(argv + ["--profiles", "off", "--envelope", "20", "--draws", "2", "--k-steps", "1", "5"]) == 0
    printed = capsys.readouterr().out
    assert "Sim-to-sim baseline: twins that differ only in the layer's seed (0 against 1…19)" in printed
    assert "th percentile of the twins'" in printed and "Reading the divergence" in printed
    envelope = (log.parent / "env_envelope.csv").read_text().splitlines()
    assert envelope[0] == "quantity,real,p5,median,p95,percentile" and len(envelope) == 5
    assert all(0.0 <= float(row.split(",")[-1]) <= 100.0 for row in envelope[1:])
    kstep = (log.parent / "env_kstep.csv").read_text().splitlines()
    n = read_run_log(str(log)).n
    assert kstep[0] == "profile,k_ticks,k_s,robot,position_error_m,heading_error_rad,score_m"
    assert len(kstep) == 1 + 2 * 2 * (n + 1) and kstep[1].startswith("nominal,1,0.033,0,")
    assert "- k = 5: " in printed  # two profiles: ranked by score


def test_the_videos_task_state_is_the_runs_own(run, tmp_path):
    """The frames' task state replays main.py's task logic on the logged poses: after the 6 steps of
    a run stopped at 6, a 7-step run of the same (deterministic) export reaches the return the 6-step
    run reported; every frame draws the task's items (PCP's prey)."""
    from comat.eval.replay_draw import real_steps
    from sim2real.export import load_config

    copy = tmp_path / "pcp"
    shutil.copytree(run[0], copy)
    result = run_rps(copy, max_steps=6)
    log7 = read_run_log(run_rps(copy, max_steps=7)["run_log"])
    frames = real_steps(log7, load_config(copy), 7)
    assert len(frames) == 7 and frames[6]["ret"] == pytest.approx(result["return"], abs=1e-9)
    assert all(f["marks"].items is not None and len(f["marks"].items.xy) > 0 for f in frames)
