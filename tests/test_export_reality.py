"""The exported main.py under the reality layer (``comat export --check DIR --reality ...``,
sim2real.reality_rps): the exact script runs under the PyPI rps with late, noisy poses and executed
commands, judged on true poses, next to comat's own loop at the same level; collisions are named;
a bad level is a one-line error. With ``COMAT_RPS_V2`` the same under the 2026 V2 simulator."""

import os

import pytest

from comat.cli import main
from comat.cli.export import _print_reality, parse_team
from sim2real.check import check_submission, run_rps
from sim2real.export import export_submission

pytest.importorskip("rps")
V2 = os.environ.get("COMAT_RPS_V2")


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    """filter -> the scripted PCP policy's folder for U_test team 3 (4 robots), with that filter."""
    tmp = tmp_path_factory.mktemp("reality_export")
    return {
        f: export_submission("heuristic", "pcp", parse_team("test:3", "pcp"), tmp / f"pcp_{f}", seed=1, filter_name=f)
        for f in ("comat", "robotarium")
    }


@pytest.mark.parametrize("drive", ["rps", "unicycle"])
def test_main_py_runs_under_the_layer_and_is_judged_on_true_poses(folders, drive):
    r = run_rps(folders["comat"], reality="nominal", seed=3, drive=drive, max_steps=4)
    rec = r["reality"]
    assert (rec["reality"], rec["drive"], rec["seed"]) == ("nominal", drive, 3)
    assert rec["iterations"] >= 4 * 29 and rec["collision_pair_iterations"] == 0 and rec["first_collision"] is None
    assert rec["min_offset_centre_distance_m"] > 0.135
    assert (rec["mujoco_contact_ticks"] == 0) if drive != "rps" else rec["mujoco_contact_ticks"] is None
    assert r["filter"] == "comat" and sum(r["rps_errors"].values()) == 0
    # the layer changes what the script saw: the same seed repeats itself, another seed does not
    again = run_rps(folders["comat"], reality="nominal", seed=3, drive=drive, max_steps=4)["reality"]
    other = run_rps(folders["comat"], reality="nominal", seed=4, drive=drive, max_steps=4)["reality"]
    assert again == rec and other["min_offset_centre_distance_m"] != rec["min_offset_centre_distance_m"]


def test_check_reports_the_deployed_loop_next_to_comats(folders, capsys):
    report = check_submission(folders["robotarium"], tier="unicycle", repeats=2, reality="nominal")
    rec = report["rps"]["reality"]
    assert rec["runs"] == 2 and rec["level"] == "nominal" and rec["runs_with_collisions"] == 0
    assert len(report["rps"]["runs"]) == 2 and all("reality" in run for run in report["rps"]["runs"])
    assert report["mujoco"]["progress"] > 0.5  # comat's own loop, at nominal, on the same team and starts
    assert main(["export", "--check", str(folders["comat"]), "--tier", "unicycle", "--reality", "nominal"]) == 0
    out = capsys.readouterr().out
    assert "deployed loop under the reality layer (nominal" in out and "COLLISION" not in out


def test_a_collision_is_named_and_fails_the_check(capsys):
    """What --check prints and returns when a run collided (a report as check_submission makes it)."""
    report = {
        "rps": {
            "filter": "robotarium",
            "progress": 0.5,
            "reality": {
                "level": "stress",
                "drive": "rps",
                "runs": 3,
                "runs_with_collisions": 1,
                "collision_pair_iterations": 12,
                "mujoco_contact_ticks": None,
                "min_offset_centre_distance_m": 0.11,
                "first_collision": {"run": 2, "robots": [1, 3], "iteration": 417, "distance_m": 0.12},
            },
        },
        "mujoco": {"progress": 0.9},
    }
    assert _print_reality(["subs/pcp_3"], [report], "unicycle") == 1
    out = capsys.readouterr().out
    assert "COLLISION in subs/pcp_3: run 2 (layer seed 2), robots 1 and 3 at iteration 417" in out


def test_a_bad_level_is_a_one_line_error(folders, capsys):
    assert main(["export", "--check", str(folders["comat"]), "--reality", "harsh"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--reality must be one of ['off', 'nominal', 'stress']" in err[0] and "'harsh'" in err[0]
    assert main(["export", "--check", str(folders["comat"]), "--reality", "nominal", "--drive", "tracks"]) == 2
    assert "--drive must be one of ['rps', 'unicycle', 'wheels'], got 'tracks'" in capsys.readouterr().err


@pytest.mark.skipif(not V2, reason="set COMAT_RPS_V2 to a robotarium_python_simulator (V2) checkout")
def test_main_py_runs_under_the_layer_with_v2(folders):
    for f in ("comat", "robotarium"):
        r = run_rps(folders[f], rps_path=V2, reality="nominal", seed=1, drive="wheels", max_steps=3)
        assert r["rps"] == "v2" and r["reality"]["collision_pair_iterations"] == 0
        assert r["reality"]["overrides"] == {"start_xy_m": 0.0, "start_theta_rad": 0.0}  # the drive's own error


def test_a_bad_filter_is_a_one_line_error(tmp_path, capsys):
    assert (
        main(
            [
                "export",
                "--policy",
                "heuristic",
                "--task",
                "pcp",
                "--team",
                "test:3",
                "--out",
                str(tmp_path / "x"),
                "--filter",
                "osqp",
            ]
        )
        == 2
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--filter must be one of ['comat', 'robotarium'], got 'osqp'" in err[0]
    assert not (tmp_path / "x").exists()
