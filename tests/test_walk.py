"""The whole Sim2Real loop of docs/export.md, end to end, with the Robotarium's simulator standing in
for the robots (the 2026 V2 rps where COMAT_RPS_V2 names a checkout, else the installed one): export
the calibration experiments, run them, fit a profile; export a policy, run it, replay the run beside
its twin at that profile, calibrate from the run's own log; train at the profile."""

import os

import yaml
from test_rl import TINY_MODELS

from comat.cli import main
from comat.reality import resolve_reality


def test_export_run_replay_calibrate_and_train_at_the_profile(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    rps = ["--rps", os.environ["COMAT_RPS_V2"]] if os.environ.get("COMAT_RPS_V2") else []
    # 1. the calibration experiments: export, run (upload, run, download), fit
    assert main(["export", "--calibration", "cal", "--robots", "2"]) == 0
    assert main(["export", "--check", "cal/steps", "cal/still", "cal/ramp", "cal/spin", *rps]) == 0
    logs = [f"cal/calib_{e}.rps-{e}.npy" for e in ("steps", "still", "ramp", "spin")]
    assert main(["calibrate", *logs, "--out", "my_robots.yaml"]) == 0
    profile = resolve_reality("my_robots.yaml")
    assert profile.pose_delay_ticks == 0 and profile.pose_noise_xy_m < 1e-6  # the simulator: no gap
    # 2. a policy: export, run, replay beside its twin at the profile
    assert main(["export", "--policy", "pretrained:comat-pcp", "--team", "test:3", "--out", "subs/pcp_3"]) == 0
    assert main(["export", "--check", "subs/pcp_3", *rps]) == 0
    capsys.readouterr()
    assert main(["replay", "subs/pcp_3.rps-log/run0", "--export", "subs/pcp_3", "--reality", "my_robots.yaml"]) == 0
    assert "| progress |" in capsys.readouterr().out
    assert (tmp_path / "subs/pcp_3.rps-log/run0/replay.rrd").is_file()
    # every run is also a calibration: the policy's run alone gives the delay, the lag and the gains
    assert main(["calibrate", "subs/pcp_3.rps-log/run0", "--out", "from_run.yaml"]) == 0
    assert resolve_reality("from_run.yaml").pose_delay_ticks == 0
    # 3. train at the profile: the run's config holds its fields
    preset = tmp_path / "tiny.yaml"
    preset.write_text(
        yaml.safe_dump(
            {
                "eval_every_steps": 10**9,
                "eval_episodes_per_team": 0,
                "ppo": {"num_envs": 2, "rollout_steps": 3, "epochs": 1, "minibatches": 1},
                "models": TINY_MODELS,
            }
        )
    )
    args = ["train", "--algo", "comat", "--task", "pcp", "--preset", str(preset), "--steps", "6", "--out", "run"]
    assert main([*args, "reality=my_robots.yaml", "--quiet"]) == 0
    saved = yaml.safe_load((tmp_path / "run" / "config.yaml").read_text())["config"]["reality"]
    assert saved["pose_hold_prob"] == profile.pose_hold_prob and saved["level"] == profile.level
