"""The whole Sim2Real loop of docs/export.md, end to end, with the Robotarium's simulator standing in
for the robots (the 2026 V2 rps where COMAT_RPS_V2 names a checkout, else the installed one): export
the calibration experiments (what each declares, the folders left as exported, bad input refused), run
them (0 simulator errors, no gap), fit a profile; export a policy, run it, replay the run beside
its twin at that profile, calibrate from the run's own log; train at the profile."""

import os
import runpy

import yaml
from test_rl import TINY_MODELS

from comat.calibration.experiments import load_log
from comat.calibration.fit import fit_steps
from comat.cli import main
from comat.reality import resolve_reality
from sim2real.calibration import STARTUP_DRIVE_S


def test_export_run_replay_calibrate_and_train_at_the_profile(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    rps = ["--rps", os.environ["COMAT_RPS_V2"]] if os.environ.get("COMAT_RPS_V2") else []
    # 1. the calibration experiments: export (each folder says what to declare), run (upload, run,
    # download: 0 simulator errors, no gap), fit
    experiments = ("steps", "still", "ramp", "spin")
    assert main(["export", "--calibration", "cal", "--robots", "2"]) == 0
    for experiment in experiments:
        files = sorted(p.name for p in (tmp_path / "cal" / experiment).iterdir())
        assert files == ["calibration_schedule.py", "main.py", "rps_compat.py", "submission_config.py"]
        config = runpy.run_path(f"cal/{experiment}/submission_config.py")["CONFIG"]
        assert config["duration_s"] == round(config["loop_s"] + STARTUP_DRIVE_S)  # the start-up drive counted
    assert capsys.readouterr().out.count(" s and 2 robots") == 4  # what to declare, said per folder
    assert main(["export", "--check", *(f"cal/{e}" for e in experiments), *rps]) == 0
    printed = capsys.readouterr().out
    assert printed.count("rps errors {'boundary': 0, 'collision': 0, 'actuator': 0}") == 4
    assert "delay_ticks 0..0" in printed
    for experiment in experiments:  # the uploaded folder stays as exported
        assert sorted(p.name for p in (tmp_path / "cal" / experiment).iterdir()) == files
    logs = [f"cal/calib_{e}.rps-{e}.npy" for e in experiments]
    if not rps:  # the installed rps steers nothing (V2's barrier steers a little: test_calibration.py)
        assert "dead_zone_radps 0..0" in printed
        _, log = load_log(logs[0])
        assert all(r["delay_ticks"] == 0 and r["tau_own_s"] <= 0.005 and r["accel_radps2"] == 0 for r in fit_steps(log))
    assert main(["export", "--calibration", "cal"]) == 2  # an existing folder is refused
    assert main(["export", "--calibration", "x", "--robots", "9"]) == 2
    assert not (tmp_path / "x").exists()
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
