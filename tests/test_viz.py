"""Rerun recordings: read the .rrd back and check it against the environment's own state."""

import json
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np
import pyarrow as pa
import pytest
from rerun.chunk import RrdReader

import comat
import comat.viz.rollout as rollout_module
from comat import constants as C
from comat.cli.rollout import add_rollout_parser, add_viz_bench_parser
from comat.envs.heuristics import heuristic_actions, random_actions
from comat.envs.tap import MIN_CHANGE_MPS
from comat.tasks import env_id
from comat.team import TeamSpec, random_team
from comat.viz import EpisodeRecorder, check_rrd_path, record_episodes
from comat.viz.bench import run_viz_bench
from comat.viz.recorder import SAFETY_ARROW_S
from comat.viz.viewer import WEB_VIEWER_URL, viewer_hint

RERUN = Path(sys.executable).parent / "rerun"
TICKS = 6


def read(path, prefix="episode_0"):
    """Entity -> (static columns, temporal table sorted by step) of one episode."""
    static, batches = defaultdict(dict), defaultdict(list)
    for ch in RrdReader(path).stream():
        if not ch.entity_path.startswith(f"/{prefix}/") and ch.entity_path != f"/{prefix}":
            continue
        rb = ch.to_record_batch()
        if ch.is_static:
            static[ch.entity_path].update({n: rb.column(n) for n in rb.schema.names})
        else:
            batches[ch.entity_path].append(rb)
    temporal = {k: pa.Table.from_batches(v).sort_by("step") for k, v in batches.items()}
    return static, temporal


def column(table, name):
    return [np.asarray(v) for v in table.column(name).to_pylist()]


class Reference:
    """A second tick observer, written plainly: per step and tick, which robots the filter changed
    and which had an event (contact onset, Robotarium collision, boundary, wall, actuator)."""

    def __init__(self, core):
        self.core, self.steps, self.current = core, [], []
        self.last = np.zeros(core.teams[0].size, dtype=bool)
        core.safe.tick_observers.append(self)

    def __call__(self, nominal, filtered, events, info):
        n = self.core.teams[0].size
        contact = events.robot_contact[:n]
        flags = [
            contact & ~self.last,
            events.collision[:n],
            events.boundary[:n],
            events.wall_contact[:n],
            events.actuator[:n],
        ]
        self.last = contact.copy()
        changed = np.linalg.norm(filtered[:n] - nominal[:n], axis=1) > MIN_CHANGE_MPS
        self.current.append((changed, np.stack(flags, -1), nominal[:n].copy(), filtered[:n].copy()))

    def close_step(self):
        self.steps.append(self.current)
        self.current = []


def record_one(tmp_path, task, policy, team_size=8, seed=3):
    """One recorded episode with the env's own state kept at every step."""
    import rerun as rr

    team = random_team(np.random.default_rng(seed), task, "test", team_size)
    env = comat.make_env(env_id(task), team=team, tier="unicycle", ticks_per_step=TICKS)
    env.reset(seed=seed)
    core = env.core
    path = tmp_path / f"{task}.rrd"
    rec = rr.RecordingStream("comat-test", recording_id=f"{task}-test")
    rec.save(path)
    recorder = EpisodeRecorder(rec)
    recorder.begin(core, 0, episode=0, metadata={"policy": policy, "seed": seed})
    ref = Reference(core)
    rng = np.random.default_rng(seed)
    kept = {
        "poses": [core.poses()[0, :team_size].copy()],
        "state": [{k: v[0].copy() for k, v in core.state.items()}],
        "actions": [],
        "rewards": [],
        "terms": [],
        "coordination": [],
    }
    info = {}
    while env.agents:
        actions = (heuristic_actions(core) if policy == "heuristic" else random_actions(rng, core.mask))[0, :team_size]
        _, rewards, _, _, infos = env.step({a: int(actions[i]) for i, a in enumerate(env.agents)})
        ref.close_step()
        info = infos["robot_0"]
        terms = {t: info[f"reward/{t}"] for t in core.task.reward_terms}
        recorder.step(actions, rewards["robot_0"], terms)
        kept["poses"].append(core.poses()[0, :team_size].copy())
        kept["state"].append({k: v[0].copy() for k, v in core.state.items()})
        kept["actions"].append(actions)
        kept["rewards"].append(rewards["robot_0"])
        kept["terms"].append([terms[t] for t in core.task.reward_terms])
        kept["coordination"].append(float(core.coordination_now[0]))
    outcome = recorder.end()
    rec.disconnect()
    assert recorder.cpu_s > 0
    kept["episode"] = {k[len("episode/") :]: v for k, v in info.items() if k.startswith("episode/")}
    assert outcome == kept["episode"]
    assert core.safe.tick_observers == [ref]  # the recorder unhooked itself
    return path, team, core, kept, ref


@pytest.mark.parametrize("task,policy", [("pcp", "random"), ("hmt", "heuristic")])
def test_recording_matches_the_env(tmp_path, task, policy):
    path, team, core, kept, ref = record_one(tmp_path, task, policy)
    static, temporal = read(path)
    n, T = team.size, len(kept["rewards"])
    assert T == kept["episode"]["steps"] > 0
    w = "/episode_0/world"
    common = [
        f"{w}/robots",
        f"{w}/robots/heading",
        f"{w}/trails",
        f"{w}/actions",
        f"{w}/safety/nominal",
        f"{w}/safety/filtered",
        f"{w}/events",
        "/episode_0/reward/total",
        "/episode_0/reward/terms",
        "/episode_0/safety/counts",
    ]
    per_task = {
        "pcp": [
            f"{w}/prey",
            f"{w}/capabilities/sensing",
            f"{w}/capabilities/capture",
            "/episode_0/task/prey",
        ],
        "hmt": [
            f"{w}/capabilities/payload",
            f"{w}/capabilities/load",
            "/episode_0/task/material",
            f"{w}/zones/material_1",
            f"{w}/zones/material_2",
            f"{w}/zones/dropoff",
        ],
    }
    assert set(common + per_task[task]) <= set(temporal)
    assert {f"{w}/arena", f"{w}/robots", "/episode_0/meta"} <= set(static)

    # Rows per timeline: states at steps 0..T, outcomes at 1..T, actions at 0..T-1.
    dt_ns = round(TICKS * C.CONTROL_DT_S * 1e9)
    for entity, first, rows in [
        (f"{w}/robots", 0, T + 1),
        (f"{w}/trails", 1, T),
        (f"{w}/actions", 0, T),
        ("/episode_0/reward/terms", 1, T),
        ("/episode_0/safety/counts", 1, T),
    ]:
        table = temporal[entity]
        assert table.num_rows == rows, entity
        np.testing.assert_array_equal(table.column("step").to_numpy(), np.arange(first, first + rows))
        sim = table.column("sim_time").cast(pa.int64()).to_numpy()
        np.testing.assert_allclose(sim, np.arange(first, first + rows) * dt_ns, atol=1)

    # Robots where the env had them, and the actions it was given.
    positions = np.stack(column(temporal[f"{w}/robots"], "Points2D:positions"))
    np.testing.assert_allclose(positions, np.stack(kept["poses"])[..., :2], atol=1e-6)
    assert static[f"{w}/robots"]["Points2D:labels"].to_pylist()[0][0].startswith(f"robot_0 {team.robots[0].type}")
    np.testing.assert_array_equal(
        np.stack(column(temporal[f"{w}/actions"], "Arrows2D:class_ids")), np.stack(kept["actions"])
    )
    # Trails are appended: each step's piece starts where the robot was and ends where it is.
    strips = np.stack(column(temporal[f"{w}/trails"], "LineStrips2D:strips"))  # (T, n, points, 2)
    np.testing.assert_allclose(strips[:, :, 0], np.stack(kept["poses"][:-1])[..., :2], atol=1e-6)
    np.testing.assert_allclose(strips[:, :, -1], np.stack(kept["poses"][1:])[..., :2], atol=1e-6)

    # Rewards: the env's reward, its return, and each named term.
    total = np.stack(column(temporal["/episode_0/reward/total"], "Scalars:scalars"))
    np.testing.assert_allclose(total[:, 0], kept["rewards"])
    np.testing.assert_allclose(total[:, 1], np.cumsum(kept["rewards"]))
    np.testing.assert_allclose(np.stack(column(temporal["/episode_0/reward/terms"], "Scalars:scalars")), kept["terms"])
    assert static["/episode_0/reward/terms"]["SeriesLines:names"].to_pylist()[0] == list(core.task.reward_terms)

    # Safety: per-step counters add up to the env's episode metrics; arrows where the filter acted.
    counts = np.stack(column(temporal["/episode_0/safety/counts"], "Scalars:scalars"))
    names = static["/episode_0/safety/counts"]["SeriesLines:names"].to_pylist()[0]
    for k, name in enumerate(names):
        assert counts[:, k].sum() == kept["episode"][name], name
    changed = np.array([np.any([t[0] for t in ticks], axis=0) for ticks in ref.steps])  # (T, n)
    nominal = column(temporal[f"{w}/safety/nominal"], "Arrows2D:vectors")
    filtered = column(temporal[f"{w}/safety/filtered"], "Arrows2D:vectors")
    assert [len(v) for v in nominal] == [len(v) for v in filtered] == changed.sum(axis=1).tolist()
    for t, ticks in enumerate(ref.steps):  # each arrow pair: the robot's tick of largest change
        for j, i in enumerate(np.flatnonzero(changed[t])):
            size = [np.linalg.norm(f[i] - m[i]) if c[i] else -1.0 for c, _, m, f in ticks]
            worst = ticks[int(np.argmax(size))]
            np.testing.assert_allclose(nominal[t][j], SAFETY_ARROW_S * worst[2][i], atol=1e-6)
            np.testing.assert_allclose(filtered[t][j], SAFETY_ARROW_S * worst[3][i], atol=1e-6)
    if task == "pcp":  # eight robots moving at random in the spawn area: the filter has work to do
        assert kept["episode"]["interventions"] > 0 and changed.any()
    events = np.array([np.any([t[1] for t in ticks], axis=(0, 2)) for ticks in ref.steps])  # (T, n)
    markers = [len(v) for v in column(temporal[f"{w}/events"], "Points2D:positions")]
    assert markers == events.sum(axis=1).tolist()
    log = temporal["/episode_0/events"]  # a line per step with events or a braking team, else one saying so
    expect = int((events.any(axis=1) | (counts[:, names.index("fallbacks")] > 0)).sum())
    assert log.num_rows == max(expect, 1)

    # Task state.
    final = kept["state"][-1]
    if task == "pcp":
        colors = column(temporal[f"{w}/prey"], "Points2D:colors")[-1]
        from comat.viz.scene import PREY_COLORS

        expect = PREY_COLORS[np.where(final["captured"], 2, np.where(final["sensed"], 1, 0))]
        np.testing.assert_array_equal(
            np.array(colors, dtype=np.uint32),
            (expect.astype(np.uint32) << np.array([24, 16, 8, 0], np.uint32)).sum(-1),
        )
        prey = np.stack(column(temporal["/episode_0/task/prey"], "Scalars:scalars"))
        np.testing.assert_array_equal(prey[:, 1], [s["captured"].sum() for s in kept["state"]])
        sensing = team.type_ids() == 0
        # The sensing radii as outlines around each sensing robot: every point of the last step's circles
        # lies at its robot's radius from the robot.
        rings = np.stack(column(temporal[f"{w}/capabilities/sensing"], "LineStrips2D:strips")[-1])  # (m, S+1, 2)
        centre = np.asarray(kept["poses"][-1])[sensing, :2]
        np.testing.assert_allclose(
            np.hypot(*(rings - centre[:, None]).transpose(2, 0, 1)),
            np.repeat(team.capability_array()[sensing, 0][:, None], rings.shape[1], 1),
            rtol=1e-5,
        )
    else:
        material = np.stack(column(temporal["/episode_0/task/material"], "Scalars:scalars"))
        np.testing.assert_allclose(material[:, :2], [s["left"] for s in kept["state"]])
        np.testing.assert_allclose(material[:, 2], [s["load"][:n].sum() for s in kept["state"]])
        np.testing.assert_allclose(material[:, 3], [s["delivered"] for s in kept["state"]])
        assert material[-1, 3] > 0  # the heuristic delivers something
        bars = np.stack(column(temporal[f"{w}/capabilities/load"], "LineStrips2D:strips"))  # (T+1, n, 2, 2)
        payload = team.capability_array()[:, 1]
        fill = (bars[:, :, 1, 0] - bars[:, :, 0, 0]) / (payload * 0.006)
        np.testing.assert_allclose(fill, np.stack([s["load"][:n] for s in kept["state"]]) / payload, atol=1e-4)

    # The task's coordination metric beside its counters: after each step, and the episode's mean so far.
    coord = temporal["/episode_0/task/coordination"]
    np.testing.assert_array_equal(coord.column("step").to_numpy(), np.arange(1, T + 1))
    values = np.stack(column(coord, "Scalars:scalars"))
    np.testing.assert_allclose(values[:, 0], kept["coordination"])
    np.testing.assert_allclose(values[-1, 1], kept["episode"]["coordination"])
    names = static["/episode_0/task/coordination"]["SeriesLines:names"].to_pylist()[0]
    assert names == [core.task.coordination_name, "episode mean"]

    # Metadata: team composition with each robot's type and capabilities, policy and seed.
    meta = static["/episode_0/meta"]
    assert meta["robot_types"].to_pylist()[0] == [r.type for r in team.robots]
    np.testing.assert_allclose(meta["capabilities"].to_pylist()[0], team.capability_array().ravel())
    assert meta["policy"].to_pylist()[0] == [policy] and meta["tier"].to_pylist() != []
    text = meta["TextDocument:text"].to_pylist()[0][0]
    assert "| robot_0 | " + team.robots[0].type in text and "Outcome" in text


def test_file_passes_rerun_verify_and_holds_every_episode(tmp_path):
    out = tmp_path / "two.rrd"
    result = record_episodes(
        out, "pcp", "heuristic", episodes=2, coalitions="test", seed=5, tier="unicycle", ticks_per_step=TICKS
    )
    assert result.path == out and out.stat().st_size == result.bytes > 0
    assert not list(tmp_path.glob(".*"))  # the temporary file was renamed into place
    verify = subprocess.run([str(RERUN), "rrd", "verify", str(out)], check=False, capture_output=True, text=True)
    assert verify.returncode == 0, verify.stderr
    printed = subprocess.run([str(RERUN), "rrd", "print", str(out)], check=True, capture_output=True, text=True).stdout
    assert "Blueprint" in printed  # the layout travels with the file
    for k, episode in enumerate(result.episodes):
        _, temporal = read(out, f"episode_{k}")
        assert temporal[f"/episode_{k}/world/robots"].num_rows == episode["steps"] + 1
        assert temporal[f"/episode_{k}/reward/total"].num_rows == episode["steps"]
    assert result.robot_steps == sum(e["steps"] * e["team_size"] for e in result.episodes)


def test_recording_does_not_change_the_episodes(tmp_path):
    kwargs = {"episodes": 2, "coalitions": "train", "seed": 11, "tier": "unicycle", "ticks_per_step": 4}
    recorded = record_episodes(tmp_path / "a.rrd", "hmt", "random", **kwargs)
    plain = record_episodes(None, "hmt", "random", **kwargs)
    assert recorded.episodes == plain.episodes and plain.path is None and plain.bytes == 0


def test_disabled_recorder_does_nothing():
    env = comat.make_env("pcp_v0", tier="unicycle", ticks_per_step=2)
    env.reset(seed=0)
    recorder = EpisodeRecorder(None)
    assert not recorder.enabled
    recorder.begin(env.core, 0)
    recorder.step(np.zeros(env.team.size, dtype=int), 0.0, {})
    assert recorder.end() is None and env.core.safe.tick_observers == [] and recorder.cpu_s == 0
    with pytest.raises(TypeError, match="recording must be a rerun.RecordingStream or None, got str"):
        EpisodeRecorder("file.rrd")


def test_recorder_misuse_is_reported(tmp_path):
    import rerun as rr

    rec = rr.RecordingStream("comat-test")
    rec.save(tmp_path / "x.rrd")
    env = comat.make_env("pcp_v0", tier="unicycle", ticks_per_step=2)
    env.reset(seed=0)
    recorder = EpisodeRecorder(rec)
    with pytest.raises(RuntimeError, match="outside an episode"):
        recorder.step(np.zeros(env.team.size, dtype=int), 0.0, {})
    recorder.begin(env.core, 0)
    with pytest.raises(RuntimeError, match="while an episode is being recorded"):
        recorder.begin(env.core, 0)
    with pytest.raises(ValueError, match=rf"actions must have shape \({env.team.size},\)"):
        recorder.step(np.zeros(env.team.size + 1, dtype=int), 0.0, {})
    recorder.end()
    rec.disconnect()


def _no_env(*args, **kwargs):
    raise AssertionError("an environment was built although the input was bad")


@pytest.mark.parametrize(
    "make,message",
    [
        (lambda d: d / "missing" / "x.rrd", "folder .*missing' does not exist"),
        (lambda d: d / "file.txt" / "x.rrd", "file.txt' is not a folder"),
        (lambda d: d, "must be a file name ending in .rrd"),
        (lambda d: d / "dir.rrd", "which is a folder"),
        (lambda d: d / "x.txt", "ending in .rrd, got"),
    ],
)
def test_bad_output_paths_fail_before_anything_runs(tmp_path, monkeypatch, make, message):
    (tmp_path / "file.txt").write_text("")
    (tmp_path / "dir.rrd").mkdir()
    monkeypatch.setattr(rollout_module, "make_env", _no_env)
    with pytest.raises(ValueError, match=message):
        record_episodes(make(tmp_path), "pcp", "heuristic")


@pytest.mark.skipif(not Path("/sys").is_dir(), reason="needs a read-only folder (/sys)")
def test_unwritable_folder_fails_before_anything_runs(monkeypatch):
    monkeypatch.setattr(rollout_module, "make_env", _no_env)
    with pytest.raises(ValueError, match="cannot write in folder '/sys'"):
        check_rrd_path("/sys/comat-test.rrd")


def test_policy_task_mismatch_and_unknown_policy_fail_before_anything_runs(tmp_path, monkeypatch, capsys):
    from comat.rl.checkpoint import save_checkpoint

    ckpt = save_checkpoint(
        tmp_path / "hmt.pt", algo="mappo", task="hmt", config={}, progress={}, trainer={}, env_rngs=[]
    )
    monkeypatch.setattr(rollout_module, "make_env", _no_env)
    out = tmp_path / "x.rrd"
    with pytest.raises(ValueError, match="is for task 'hmt', expected 'pcp'"):
        record_episodes(out, "pcp", ckpt)
    with pytest.raises(
        ValueError,
        match=r"policy must be one of \('heuristic', 'type_only', 'blind', 'constant', 'random', 'scripted'\) or a "
        r"checkpoint file, got 'greedy'",
    ):
        record_episodes(out, "pcp", "greedy")
    with pytest.raises(ValueError, match="episodes must be a positive integer, got 0"):
        record_episodes(out, "pcp", "heuristic", episodes=0)
    with pytest.raises(ValueError, match="teams\\[0\\] is a 'hmt' team, but the rollout runs 'pcp'"):
        record_episodes(out, "pcp", "heuristic", teams=[random_team(np.random.default_rng(0), "hmt", "test", 3)])
    args = _parser().parse_args(["rollout", "--task", "pcp", "--policy", str(ckpt), "--out", str(out)])
    with pytest.raises(ValueError, match="--task 'pcp' disagrees with the checkpoint, which is for task 'hmt'"):
        args.func(args)
    assert capsys.readouterr().err == ""  # refused before the rollout was even announced
    assert not out.exists()


def _parser():
    import argparse

    parser = argparse.ArgumentParser(prog="comat")
    sub = parser.add_subparsers(dest="command", required=True)
    add_rollout_parser(sub)
    bench = sub.add_parser("bench").add_subparsers(dest="what", required=True)
    add_viz_bench_parser(bench)
    return parser


def test_rollout_command_writes_the_file_and_says_how_to_open_it(tmp_path, capsys):
    out = tmp_path / "pcp.rrd"
    args = _parser().parse_args(
        [
            "rollout",
            "--task",
            "pcp",
            "--policy",
            "random",
            "--episodes",
            "1",
            "--tier",
            "unicycle",
            "--ticks-per-step",
            "3",
            "--out",
            str(out),
        ]
    )
    assert args.func(args) == 0
    printed = capsys.readouterr().out
    assert viewer_hint(out) in printed and "episode 0:" in printed
    assert out.exists()
    with pytest.raises(SystemExit):
        _parser().parse_args(["rollout", "--task", "pcp", "--episodes", "0"])
    assert "expected a positive integer, got '0'" in capsys.readouterr().err
    args = _parser().parse_args(["bench", "viz", "--tasks", "hmt", "--episodes", "2"])
    assert args.tasks == ["hmt"] and args.func.__name__ == "cmd_viz_bench"


def test_checkpoint_policy_is_recorded(tmp_path):
    from comat.rl import resolve, train

    preset = {
        "total_env_steps": 6,
        "eval_every_steps": 10**9,
        "eval_episodes_per_team": 0,
        "checkpoint_every_steps": 6,
        "ppo": {"num_envs": 2, "rollout_steps": 3, "epochs": 1, "minibatches": 1},
        "models": {"mappo": {"hidden": 16}},
    }
    train(resolve(preset, "mappo", "hmt", seed=1, tier="unicycle"), tmp_path / "run", quiet=True)
    team = random_team(np.random.default_rng(2), "hmt", "test", 4)
    out = tmp_path / "ckpt.rrd"
    result = record_episodes(out, "hmt", tmp_path / "run" / "checkpoint.pt", teams=[team], ticks_per_step=2)
    static, temporal = read(out)
    assert static["/episode_0/meta"]["policy"].to_pylist()[0] == ["mappo checkpoint checkpoint.pt"]
    assert static["/episode_0/meta"]["tier"].to_pylist()[0] == ["unicycle"]  # the checkpoint's tier
    assert temporal["/episode_0/world/robots"].num_rows == result.episodes[0]["steps"] + 1
    # Another run's checkpoint under the same file name gets its own recording id.
    import shutil
    from unittest import mock

    (tmp_path / "run2").mkdir()
    shutil.copy(tmp_path / "run" / "checkpoint.pt", tmp_path / "run2" / "checkpoint.pt")
    ids = []

    class Spy(rollout_module.rr.RecordingStream):
        def __init__(self, *args, **kwargs):
            ids.append(kwargs["recording_id"])
            super().__init__(*args, **kwargs)

    with mock.patch.object(rollout_module.rr, "RecordingStream", Spy):
        for run in ("run", "run2"):
            record_episodes(out, "hmt", tmp_path / run / "checkpoint.pt", teams=[team], ticks_per_step=2)
    assert len(ids) == 2 and ids[0] != ids[1]


def test_bench_reports_overhead_and_bytes_per_robot_step(tmp_path, capsys):
    out = tmp_path / "viz.json"
    doc = run_viz_bench(("pcp",), episodes=1, repeats=1, ticks_per_step=2, out=out)
    assert json.loads(out.read_text()) == doc
    r = doc["results"][0]
    assert r["robot_steps"] == r["steps"] * r["team_sizes"][0] > 0
    assert r["bytes_per_robot_step"] == pytest.approx(r["bytes"] / r["robot_steps"])
    assert 0 < r["payload_bytes_per_robot_step"] < r["bytes_per_robot_step"]
    for clock in ("wall", "cpu"):
        assert r[f"overhead_{clock}"] == pytest.approx(r[f"recorded_{clock}_s"] / r[f"plain_{clock}_s"] - 1)
        assert len(r["runs"]["recorded"]) == len(r["runs"]["plain"]) == 1
    assert 0 < r["recorder_cpu_s"] < r["recorded_cpu_s"] and r["background_cpu_s"] >= 0
    assert r["attributed_overhead_cpu"] == pytest.approx(
        (r["recorder_cpu_s"] + r["background_cpu_s"]) / r["plain_cpu_s"]
    )
    assert "B/robot-step" in capsys.readouterr().out
    with pytest.raises(ValueError, match="repeats must be a positive integer, got 0"):
        run_viz_bench(("pcp",), repeats=0, out=None)


def test_command_line_registration_does_not_import_rerun():
    # comat.cli imports comat.cli.rollout for every command; Rerun (seconds to import) loads on use.
    code = "import sys, comat.cli.rollout; assert 'rerun' not in sys.modules, sorted(sys.modules)"
    subprocess.run([sys.executable, "-c", code], check=True)


def test_each_episode_records_its_own_team(tmp_path):
    """A two-episode recording of the coalition set, read back: every episode's meta holds the
    types and capabilities of the team that episode ran (the env has moved on by then)."""
    from comat.envs.base import resolve_coalitions

    out = tmp_path / "two.rrd"
    teams = resolve_coalitions("test", "pcp")[:2]
    assert teams[0].size != teams[1].size
    result = record_episodes(out, "pcp", "heuristic", teams=teams, ticks_per_step=2, max_robots=8)
    for k, team in enumerate(teams):
        meta = read(out, prefix=f"episode_{k}")[0][f"/episode_{k}/meta"]
        assert meta["robot_types"].to_pylist()[0] == [r.type for r in team.robots]
        np.testing.assert_allclose(meta["capabilities"].to_pylist()[0], team.capability_array().ravel())
        assert float(meta["outcome_steps"].to_pylist()[0][0]) == result.episodes[k]["steps"]


def test_the_viewer_hint_works_on_the_machine_it_is_printed_on():
    """Without a display the native viewer cannot start: the hint serves the web viewer (issue 32)."""
    assert viewer_hint("a b.rrd", {"DISPLAY": ":0"}) == "open it with: rerun 'a b.rrd'"
    assert viewer_hint("x.rrd", {"WAYLAND_DISPLAY": "wayland-0"}).startswith("open it with: rerun")
    headless = viewer_hint("x.rrd", {})
    if sys.platform not in ("darwin", "win32"):
        assert "rerun --serve-web x.rrd" in headless and WEB_VIEWER_URL in headless and "ssh -L 9090" in headless


def test_a_shipped_policy_is_named_as_such_in_recordings_and_videos(tmp_path):
    """The header of a recording (and each video frame's caption) names ``pretrained:NAME``, not the
    file the name resolves to; a copy of that file elsewhere is just a checkpoint file."""
    import shutil

    from comat.rl import pretrained_path
    from comat.viz.rollout import resolve_policy

    shipped = pretrained_path("comat-pcp")
    assert resolve_policy(shipped, "pcp").name == "pretrained:comat-pcp"
    copy = shutil.copyfile(shipped, tmp_path / "comat_pcp_s0.pt")
    assert resolve_policy(copy, "pcp").name == "comat checkpoint comat_pcp_s0.pt"


def test_the_arena_has_a_legend_and_a_quiet_episode_says_it_had_no_events(tmp_path):
    """Rerun shows what each mark means (as the video's legend does), and an episode with nothing to
    report logs one line that says so instead of an empty events view."""
    from comat.viz.recorder import NO_EVENTS

    team = TeamSpec.from_dict(
        {
            "task": "pcp",
            "robots": [
                {"type": "sensing", "capabilities": [0.4, 0.0]},
                {"type": "capture", "capabilities": [0.0, 0.3]},
            ],
        }
    )
    path = tmp_path / "quiet.rrd"
    record_episodes(path, "pcp", "heuristic", teams=[team], ticks_per_step=2)
    static, temporal = read(path)
    labels = [str(x) for x in static["/episode_0/world/legend"]["Points2D:labels"].to_pylist()[0]]
    assert {"sensing", "capture", "prey free", "prey sensed", "prey captured"} <= set(labels), labels
    events = [str(x) for row in temporal["/episode_0/events"].column("TextLog:text").to_pylist() for x in row]
    assert events == [NO_EVENTS]
