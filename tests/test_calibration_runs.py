"""Calibration from policy runs' logs (every run is also a calibration), the fit with ``nominal``'s
nuisances on against its tolerance table, and that table in docs/calibration.md."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
import yaml

from comat.calibration.profile import fit_logs, profile_fields
from comat.calibration.recovery import NOMINAL_TOLERANCES, check_level, recover_level, tolerance_markdown
from comat.cli import main
from sim2real.check import run_rps

ROOT = Path(__file__).resolve().parents[1]
KNOWN = {
    "level": "off",
    "pose_delay_ticks": 2,
    "motor_tau_min_s": 0.06,
    "motor_tau_max_s": 0.06,
    "wheel_gain_mean": 0.95,
    "pose_hold_prob": 0.2,
    "pose_noise_xy_m": 0.0005,
}
UNICYCLE_TIER_TAU_S = 0.025
"""The MuJoCo unicycle tier's own servo lag (results/calibration/recovery.md), on top of the layer's."""


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    folder = tmp_path_factory.mktemp("runs") / "pcp"
    assert main(["export", "--policy", "pretrained:comat-pcp", "--team", "test:3", "--out", str(folder)]) == 0
    return folder


def _estimates(fit: dict) -> dict:
    return {p["name"]: p for p in fit["parameters"]}


def test_a_run_under_a_known_layer_gives_its_delay_lag_gains_and_holds(folder, tmp_path):
    """A stand-in run (the exported folder's main.py, the robots moved by MuJoCo's unicycle tier
    under a known layer): the fit of its comat_run.npy finds the delay exactly, the lag between the
    layer's and the layer's plus the tier's own, the speed and turn gains within 0.02 and the holds
    within 20 %; the profile writes those and says what a run cannot show."""
    profile = tmp_path / "known.yaml"
    profile.write_text(yaml.safe_dump({"reality": KNOWN}))
    log = run_rps(folder, max_steps=30, reality=str(profile), seed=0, drive="unicycle")["run_log"]
    fit = fit_logs([log])
    est = _estimates(fit)
    assert est["pose_delay_ticks"]["lo"] == est["pose_delay_ticks"]["hi"] == 2
    assert 0.8 * 0.06 <= est["motor_tau_s"]["estimate"] <= 1.2 * (0.06 + UNICYCLE_TIER_TAU_S)
    assert est["motor_tau_s"]["interval"] == "t95"  # over the robots' own lags, not a zero-width one
    assert abs(est["speed_gain"]["estimate"] - 0.95) <= 0.02 and abs(est["turn_gain"]["estimate"] - 0.95) <= 0.02
    assert abs(est["pose_hold_prob"]["estimate"] - 0.2) <= 0.04
    assert est["top_speed_derate_min"]["estimate"] is None and "steps or spin" in est["top_speed_derate_min"]["note"]
    fields = profile_fields(fit)
    assert fields["pose_delay_ticks"] == 2 and abs(fields["wheel_gain_mean"] - 0.95) <= 0.02
    assert "top_speed_derate_min" not in fields and "pose_noise_xy_m" not in fields


def test_a_run_under_rps_shows_no_gap_and_calibrate_takes_the_runs_folder(folder, tmp_path, capsys):
    """The Robotarium simulator (legacy PyPI rps) has no delay, lag or gain: the run's fit finds none,
    and ``comat calibrate RUN_FOLDER`` writes a profile from it."""
    log = run_rps(folder, max_steps=30)["run_log"]
    est = _estimates(fit_logs([log]))
    assert est["pose_delay_ticks"]["hi"] == 0 and est["motor_tau_s"]["estimate"] <= 0.005
    assert abs(est["speed_gain"]["estimate"] - 1) < 0.01 and abs(est["turn_gain"]["estimate"] - 1) < 0.01
    out = tmp_path / "from_run.yaml"
    assert main(["calibrate", log, "--out", str(out)]) == 0
    data = yaml.safe_load(out.read_text())
    assert data["reality"]["pose_delay_ticks"] == 0 and "from run" in capsys.readouterr().out
    assert data["not_identified"]["top_speed_derate_min"].startswith("nominal's 0.9: not identified (needs a steps")


def test_a_folder_without_a_run_log_is_one_line(tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    assert main(["calibrate", str(tmp_path / "empty"), "--out", str(tmp_path / "p.yaml")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "comat_run.npy" in err and not (tmp_path / "p.yaml").exists()


@pytest.mark.parametrize("seed", [0, 9])
def test_nominal_nuisances_on_every_parameter_within_its_tolerance(seed, tmp_path):
    """The four experiments simulated at ``nominal`` (mixed delays with jitter, per-wheel lags, the
    wheels' disturbance, command loss, freezes, bias) and fitted as ``comat calibrate`` does: every
    row of the tolerance table holds (results/calibration/recovery.md runs twelve seeds)."""
    got = check_level(recover_level("nominal", seed, tmp_path))
    assert set(got) == set(NOMINAL_TOLERANCES)
    assert all(ok for ok, _ in got.values()), {k: v for k, v in got.items() if not v[0]}


def test_the_tolerance_table_in_the_docs_is_the_one_checked():
    page = (ROOT / "docs" / "calibration.md").read_text()
    assert tolerance_markdown() in page


@pytest.mark.skipif(
    not os.environ.get("COMAT_RPS_V2"), reason="set COMAT_RPS_V2 to a robotarium_python_simulator (V2) checkout"
)
def test_a_run_under_rps_v2_shows_no_delay_and_unit_gains(folder):
    log = run_rps(folder, max_steps=30, rps_path=os.environ["COMAT_RPS_V2"])["run_log"]
    est = _estimates(fit_logs([log]))
    assert est["pose_delay_ticks"]["hi"] == 0
    assert np.isclose(est["speed_gain"]["estimate"], 1, atol=0.02) and np.isclose(
        est["turn_gain"]["estimate"], 1, atol=0.02
    )
