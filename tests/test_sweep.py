"""``comat sweep`` on Ray Tune: swept runs equal ``comat train`` runs, a second sitting skips them,
progress lines and the recorded command, ``--status`` from the sweep's record, one-line errors for
bad inputs; marked ``cluster`` (``make test-cluster``): kill -9 of the sweep at random moments, and a
two-node Ray cluster on loopback whose worker is killed mid-run."""

import contextlib
import json
import os
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from test_rl import TINY_MODELS, assert_same

from comat.cli import main
from comat.eval.sweep import RECORD, param_space, prepare_sweep, sweep_status
from comat.rl import load_checkpoint, load_preset, resolve, train

ROOT = Path(__file__).resolve().parents[1]


def _preset(folder: Path, steps: int = 12) -> Path:
    """A preset whose runs take seconds: one CPU per trial, no evaluation during training."""
    path = folder / "tiny.yaml"
    path.write_text(
        yaml.safe_dump(
            {
                "total_env_steps": steps,
                "seeds": [0],
                "eval_every_steps": 10**9,
                "eval_episodes_per_team": 0,
                "checkpoint_every_steps": 6,
                "tier": "unicycle",
                "torch_threads": 1,
                "ppo": {"num_envs": 2, "rollout_steps": 3, "epochs": 1, "minibatches": 1},
                "models": TINY_MODELS,
            }
        )
    )
    return path


def _comat(*args: str, cwd: Path, env: dict | None = None, timeout: float = 600) -> subprocess.CompletedProcess:
    env = {**os.environ, **(env or {}), "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    return subprocess.run(
        [sys.executable, "-m", "comat.cli", *args],
        check=False,
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
    )


def _straight(preset: Path, algo: str, seed: int, out: Path) -> dict:
    """The same run trained by ``comat train``'s own function, in this process."""
    train(resolve(load_preset(preset), algo, "pcp", seed=seed), out, quiet=True)
    return load_checkpoint(out / "checkpoint.pt")


def test_swept_runs_equal_comat_train_runs_and_a_second_sitting_skips_them(tmp_path):
    """Two jobs on a local Ray instance, from another working directory with a relative --out: the
    run folders land under that --out, their checkpoints equal `comat train`'s bit for bit, each
    config.yaml records the sweep command, progress is printed while they run, and running the
    command again starts nothing."""
    preset = _preset(tmp_path)
    (tmp_path / "elsewhere").mkdir()
    root = tmp_path / "elsewhere" / "sw"
    (root / "mat_pcp_s0").mkdir(parents=True)  # a run stopped before its first checkpoint, by hand
    (root / "mat_pcp_s0" / "config.yaml").write_text("partial")
    argv = [
        "sweep",
        "--preset",
        str(preset),
        "--algos",
        "comat",
        "mat",
        "--tasks",
        "pcp",
        "--eval-sets",
        "train",
        "--out",
        "sw",
        "--jobs",
        "2",
    ]
    first = _comat(*argv, cwd=tmp_path / "elsewhere")
    assert first.returncode == 0, first.stderr[-3000:]
    out = first.stdout
    assert "seeds [0] from the preset" in out and "2 jobs, 0 finished, 2 to run" in out
    assert "started comat/pcp/s0" in out and "comat/pcp/s0: 6 / 12 env steps" in out, out
    assert out.index("comat/pcp/s0: 6 / 12") < out.index("done comat/pcp/s0: 12 env steps")
    assert f"comat report {root}/*_s*" in out
    assert (root / ".aborted" / "mat_pcp_s0-1" / "config.yaml").read_text() == "partial"  # kept, set aside
    record = json.loads((root / RECORD).read_text())
    assert record["root"] == str(root) and record["seeds"] == [0] and record["seeds_from"] == "preset"
    for algo in ("comat", "mat"):
        run = root / f"{algo}_pcp_s0"
        recorded = yaml.safe_load((run / "config.yaml").read_text())["command"]  # paths as typed where it ran
        assert recorded == ["comat", *argv[:2], "../tiny.yaml", *argv[3:]] and argv[2] == str(tmp_path / "tiny.yaml")
        assert json.loads((run / "evaluation_unicycle.json").read_text())
        swept, straight = load_checkpoint(run / "checkpoint.pt"), _straight(preset, algo, 0, tmp_path / algo)
        assert swept["progress"]["env_steps"] == straight["progress"]["env_steps"] == 12
        assert_same(swept["trainer"], straight["trainer"], f"{algo}.trainer")
    again = _comat("sweep", "--out", "sw", cwd=tmp_path / "elsewhere")
    assert again.returncode == 0 and "continuing the sweep recorded in" in again.stdout
    assert "2 jobs, all finished" in again.stdout and "Started a local Ray instance" not in again.stderr


def test_tune_runs_the_jobs_seed_major():
    """The order Tune generates trials in (its variant generator, as Tuner uses it): seed 0 of every
    algorithm and task before any seed 1, so a sweep stopped early compares all cells."""
    pytest.importorskip("ray")
    from ray.tune.search.variant_generator import generate_variants

    record = {"algos": ["comat", "mat", "qmix"], "tasks": ["pcp", "hmt"], "seeds": [0, 1]}
    order = [(v["job"]["seed"], v["job"]["task"], v["job"]["algo"]) for _, v in generate_variants(param_space(record))]
    assert order == [(s, t, a) for s in (0, 1) for t in ("pcp", "hmt") for a in ("comat", "mat", "qmix")]
    assert all(v["sweep"] == record for _, v in generate_variants(param_space(record)))


def _progress(folder, rows):
    folder.mkdir(parents=True)
    folder.joinpath("progress.csv").write_text("env_steps,updates,wall_s\n" + "".join(f"{e},1,{w}\n" for e, w in rows))


def test_sweep_status_reads_the_grid_from_the_record(tmp_path, capsys):
    preset = tmp_path / "p.yaml"
    preset.write_text(yaml.safe_dump({"total_env_steps": 10000, "seeds": [0, 1, 2]}))
    root = tmp_path / "sweep"
    _progress(root / "comat_pcp_s0", [(5000, 50.0), (10240, 100.0)])  # done: summary + evaluation
    for name in ("summary.json", "evaluation_unicycle.json", "checkpoint.pt"):
        (root / "comat_pcp_s0" / name).write_text("{}")
    _progress(root / "comat_pcp_s1", [(2000, 40.0), (4000, 80.0)])  # 50 env-steps/s, 6000 left
    (root / "comat_pcp_s1" / "checkpoint.pt").write_text("")
    record, notes = prepare_sweep(root, {"algos": ["comat"], "tasks": ["pcp", "hmt"], "preset": str(preset)})
    assert notes == [f"seeds [0, 1, 2] from the preset {str(preset)!r} (--seeds changes them)"]
    rows = {r["seed"]: r for r in sweep_status(root, record) if r["task"] == "pcp"}
    assert [rows[s]["state"] for s in (0, 1, 2)] == ["done", "resume", "new"]
    assert rows[0]["hours_left"] == 0.0 and rows[0]["env_steps_per_s"] == pytest.approx(102.4)
    assert rows[1]["env_steps"] == 4000 and rows[1]["hours_left"] == pytest.approx(6000 / 50 / 3600)
    # a job not started: the mean rate of the task's other runs, (102.4 + 50) / 2
    assert rows[2]["hours_left"] == pytest.approx(10000 / 76.2 / 3600)
    hmt = [r for r in sweep_status(root, record) if r["task"] == "hmt"]
    assert hmt[0]["state"] == "new" and hmt[0]["hours_left"] is None  # no HMT run yet: no rate
    # The record, as a sweep writes it when it starts; --status then needs no grid flags.
    (root / RECORD).write_text(json.dumps(record))
    assert main(["sweep", "--status", "--jobs", "2", "--out", str(root)]) == 0
    out = capsys.readouterr().out
    assert "comat_pcp_s1 resume 4,000 / 10,000 50 0:02" in [" ".join(line.split()) for line in out.splitlines()]
    assert "1 of 6 jobs done" in out and not (root / "comat_pcp_s2").exists()
    # Without a record (a sweep from before records were kept) the flags give the grid, as they did.
    (root / RECORD).unlink()
    assert (
        main(["sweep", "--status", "--preset", str(preset), "--algos", "comat", "--tasks", "pcp", "--out", str(root)])
        == 0
    )
    assert "1 of 3 jobs done" in capsys.readouterr().out


def test_seeds_given_replace_the_presets_and_the_sweep_says_so(tmp_path):
    preset = _preset(tmp_path)
    record, notes = prepare_sweep(tmp_path / "sw", {"preset": str(preset), "seeds": [4, 5]})
    assert record["seeds"] == [4, 5] and record["seeds_from"] == "--seeds"
    assert notes == ["seeds [4, 5] from --seeds (the preset's: [0])"]
    assert record["cpus_per_trial"] == 1 and not (tmp_path / "sw").exists()  # checked, nothing written yet
    assert prepare_sweep(tmp_path / "sw", {"preset": "paper"})[0]["cpus_per_trial"] == 2  # 2 env processes


@pytest.mark.parametrize(
    "case",
    [
        "preset_missing",
        "preset_unknown",
        "preset_empty",
        "preset_bytes",
        "preset_negative",
        "override_unknown",
        "seeds_negative",
        "seeds_repeated",
        "steps_zero",
        "episodes_zero",
        "jobs_zero",
        "retries_negative",
        "out_is_a_file",
        "out_unwritable",
        "out_under_a_file",
        "out_is_a_run",
        "out_holds_another_sweep",
        "record_corrupt",
    ],
)
def test_bad_sweep_inputs_get_one_line_and_leave_nothing(tmp_path, capsys, case):
    """Exit status 2, one line naming the argument, the expected and the received value, no
    traceback, and nothing written (no root folder; an existing sweep's record unchanged)."""
    preset = _preset(tmp_path)
    path = tmp_path / "input"
    out = tmp_path / "out"
    base = ["sweep", "--preset", str(preset), "--algos", "comat", "--tasks", "pcp", "--no-eval"]
    if case in ("preset_empty", "out_is_a_file"):
        path.write_text("")
    elif case == "preset_bytes":
        path.write_bytes(bytes(np.random.default_rng(0).integers(0, 256, 512, dtype=np.uint8)))
    elif case == "preset_negative":
        path.write_text("total_env_steps: -5\n")
    elif case == "out_is_a_run":
        out.mkdir()
        (out / "config.yaml").write_text("config: {}\n")
    elif case in ("out_holds_another_sweep", "record_corrupt"):
        out.mkdir()
        (out / RECORD).write_text(
            "{not json"
            if case == "record_corrupt"
            else json.dumps(
                prepare_sweep(out, {"preset": str(preset), "algos": ["comat"], "tasks": ["pcp"], "eval_sets": []})[0]
            )
        )
    argv, expected = {
        "preset_missing": ([*base, "--preset", str(tmp_path / "nope.yaml"), "--out", str(out)], "does not exist"),
        "preset_unknown": ([*base, "--preset", "nosuch", "--out", str(out)], "unknown preset 'nosuch'; presets: ["),
        "preset_empty": ([*base, "--preset", str(path.with_suffix(".yaml")), "--out", str(out)], "is empty"),
        "preset_bytes": ([*base, "--preset", str(path.with_suffix(".yaml")), "--out", str(out)], "is not"),
        "preset_negative": (
            [*base, "--preset", str(path.with_suffix(".yaml")), "--out", str(out)],
            "total_env_steps must be an integer >= 1, got -5",
        ),
        "override_unknown": ([*base, "--out", str(out), "ppo.lrr=3"], "unknown key(s) ['lrr']"),
        "seeds_negative": (
            [*base, "--seeds", "-1", "--out", str(out)],
            "--seeds must be non-negative integers, got [-1]",
        ),
        "seeds_repeated": ([*base, "--seeds", "1", "1", "--out", str(out)], "--seeds must not repeat a seed"),
        "steps_zero": ([*base, "--steps", "0", "--out", str(out)], "--steps must be an integer >= 1, got 0"),
        "episodes_zero": ([*base, "--episodes", "0", "--out", str(out)], "--episodes must be an integer >= 1, got 0"),
        "jobs_zero": ([*base, "--jobs", "0", "--out", str(out)], "--jobs must be an integer >= 1, got 0"),
        "retries_negative": (
            [*base, "--retries", "-1", "--out", str(out)],
            "--retries must be an integer >= 0, got -1",
        ),
        "out_is_a_file": ([*base, "--out", str(path)], "is a file; expected the sweep's root folder"),
        "out_unwritable": ([*base, "--out", "/sys/comat-sweep"], "cannot be written"),
        "out_under_a_file": ([*base, "--out", str(tmp_path / "tiny.yaml" / "sw")], "cannot be written"),
        "out_is_a_run": ([*base, "--out", str(out)], "is a run folder of comat train"),
        "out_holds_another_sweep": (
            [*base, "--seeds", "7", "--out", str(out)],
            "holds a sweep with other settings (--seeds [0] there, [7] given)",
        ),
        "record_corrupt": ([*base, "--out", str(out)], "cannot be read"),
    }[case]
    if case in ("preset_empty", "preset_bytes", "preset_negative"):
        path.rename(path.with_suffix(".yaml"))
    if case == "out_unwritable" and not Path("/sys").is_dir():
        pytest.skip("needs a read-only folder (/sys)")
    before = sorted(p.name for p in out.iterdir()) if out.is_dir() else None
    record_before = (out / RECORD).read_bytes() if (out / RECORD).is_file() else None
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("comat sweep: error: ") and expected in err[0], err
    assert (sorted(p.name for p in out.iterdir()) if out.is_dir() else None) == before
    assert ((out / RECORD).read_bytes() if (out / RECORD).is_file() else None) == record_before
    assert not Path("/sys/comat-sweep").exists()


# -- marked cluster: make test-cluster (.ci/run runs it) ---------------------------------------------------
def _descendants(pid: int) -> list:
    import psutil

    try:
        return psutil.Process(pid).children(recursive=True)
    except psutil.NoSuchProcess:
        return []


def _end(procs) -> None:
    """End processes this test started (by their ids): TERM, then KILL what is left after 20 s."""
    import psutil

    for p in procs:
        with contextlib.suppress(psutil.NoSuchProcess):
            p.terminate()
    _, alive = psutil.wait_procs(procs, timeout=20)
    for p in alive:
        with contextlib.suppress(psutil.NoSuchProcess):
            p.kill()


def _file_id(path: Path) -> tuple | None:
    """Which version of a file is on disk: each (atomic) write replaces it, so its inode or mtime change."""
    try:
        st = path.stat()
    except FileNotFoundError:
        return None
    return st.st_ino, st.st_mtime_ns


@pytest.mark.cluster
def test_kill_9_of_a_sweep_at_random_moments_then_rerun_equals_an_uninterrupted_run(tmp_path):
    """``comat sweep`` killed with SIGKILL in each phase of a run (while Ray starts, before the first
    checkpoint, between checkpoints, during a checkpoint write when the poll catches its temporary
    file), then run again as a user would: the checkpoint on disk always loads, the finished run equals
    an uninterrupted ``comat train`` run, and no temporary file remains.

    The kills follow what the sweep has written, not the clock, so they land in the same phases on a
    fast CI machine (where a whole 96-step sweep takes a few seconds) and on a loaded one."""
    import psutil

    preset = _preset(tmp_path, steps=96)
    root = tmp_path / "sw"
    argv = [
        sys.executable,
        "-m",
        "comat.cli",
        "sweep",
        "--preset",
        str(preset),
        "--algos",
        "comat",
        "--tasks",
        "pcp",
        "--seeds",
        "3",
        "--no-eval",
        "--out",
        str(root),
        "--jobs",
        "1",
    ]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    run = root / "comat_pcp_s3"
    rng = np.random.default_rng(0)
    phases = [
        "ray starting",
        "before the first checkpoint",
        "between checkpoints",
        "during a checkpoint write",
        "between checkpoints",
    ]
    killed_in = []
    for phase in phases:
        first, config = _file_id(run / "checkpoint.pt"), _file_id(run / "config.yaml")
        proc = subprocess.Popen(argv, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        tree: dict[int, psutil.Process] = {}
        seen, polls = {first}, 0
        while proc.poll() is None:
            if polls % 40 == 0:
                tree.update({p.pid: p for p in _descendants(proc.pid)})  # Ray's processes, to end if they linger
            polls += 1
            seen.add(_file_id(run / "checkpoint.pt"))
            new = len(seen - {first, None})  # checkpoints written in this sitting (a fast pair may count once)
            started = _file_id(run / "config.yaml") not in (None, config)  # each sitting writes it first
            if phase == "ray starting" and (tree or started):
                time.sleep(rng.uniform(0.0, 0.5))
                break
            if phase == "before the first checkpoint" and (started or new >= 1):
                break  # with a checkpoint already written the window was missed: killed right after it
            if phase == "between checkpoints" and new >= 1:
                time.sleep(rng.uniform(0.0, 0.2))
                break
            if phase == "during a checkpoint write" and (list(run.glob(".checkpoint.pt.*.tmp")) or new >= 2):
                break
            time.sleep(0.005)
        if proc.poll() is None:
            tree.update({p.pid: p for p in _descendants(proc.pid)})
            proc.send_signal(signal.SIGKILL)
            killed_in.append(phase)
        proc.wait(timeout=60)
        _, alive = psutil.wait_procs(list(tree.values()), timeout=20)  # the instance ends with its driver...
        _end(alive)  # ...but for Ray's agent processes, which outlive it
        if (run / "checkpoint.pt").exists():
            load_checkpoint(run / "checkpoint.pt")  # the one on disk is always a complete one
    assert killed_in == phases  # each sitting was killed before the run could finish
    final = subprocess.run(argv, check=False, env=env, capture_output=True, text=True, timeout=600)
    assert final.returncode == 0, final.stderr[-3000:]
    assert not list(run.glob(".*tmp*")) and not list(root.glob(".*tmp*"))
    swept, straight = load_checkpoint(run / "checkpoint.pt"), _straight(preset, "comat", 3, tmp_path / "straight")
    assert swept["progress"]["env_steps"] == straight["progress"]["env_steps"] == 96
    assert_same(swept["trainer"], straight["trainer"], "trainer")


def _free_ports(n: int) -> list[int]:
    socks = [socket.socket() for _ in range(n)]
    for s in socks:
        s.bind(("127.0.0.1", 0))
    ports = [s.getsockname()[1] for s in socks]
    for s in socks:
        s.close()
    return ports


# Ray rewrites 127.0.0.1 and localhost into this machine's network address; another address of the
# loopback range keeps every connection of the test cluster on loopback.
LOOPBACK = "127.0.0.2"


@contextlib.contextmanager
def _cluster(ray_env: dict, nodes: int = 2, dashboard: bool = False):
    """A Ray head (and ``nodes - 1`` more nodes) on loopback, one CPU each, each with its own temp
    dir; yields the head's address (and the dashboard's, for ``ray job submit``); every process
    stopped by its id on the way out."""
    import psutil

    ray = shutil.which("ray", path=str(Path(sys.executable).parent)) or shutil.which("ray")
    temps = [tempfile.mkdtemp(prefix="rn", dir="/tmp") for _ in range(nodes)]  # short: Ray's socket paths
    gcs, client, dash, *agent = _free_ports(3 + 2 * nodes)
    common = ["--node-ip-address", LOOPBACK, "--num-cpus", "1", "--disable-usage-stats"]
    cmds = [
        [
            ray,
            "start",
            "--head",
            "--port",
            str(gcs),
            "--temp-dir",
            temps[0],
            "--include-dashboard",
            str(dashboard).lower(),
            "--dashboard-host",
            LOOPBACK,
            "--dashboard-port",
            str(dash),
            "--ray-client-server-port",
            str(client),
        ]
    ]
    cmds += [[ray, "start", "--address", f"{LOOPBACK}:{gcs}", "--temp-dir", t] for t in temps[1:]]
    try:
        for k, cmd in enumerate(cmds):
            ports = ["--dashboard-agent-listen-port", str(agent[2 * k]), "--metrics-export-port", str(agent[2 * k + 1])]
            done = subprocess.run(
                [*cmd, *ports, *common], check=False, env=ray_env, cwd="/", capture_output=True, text=True, timeout=180
            )
            assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
        yield f"{LOOPBACK}:{gcs}", f"http://{LOOPBACK}:{dash}"
    finally:
        started = [
            p for p in psutil.process_iter(["cmdline"]) if any(t in " ".join(p.info["cmdline"] or []) for t in temps)
        ]
        _end(list({q.pid: q for p in started for q in [p, *_descendants(p.pid)]}.values()))
        for t in temps:
            shutil.rmtree(t, ignore_errors=True)


def _ray_env(tmp_path: Path) -> dict:
    """The environment of the test cluster's nodes: a token of its own, and no PYTHONPATH (the nodes
    do not see this checkout; the driver ships its code)."""
    token = tmp_path / "token"
    token.write_text(secrets.token_hex(32))
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env.update(RAY_AUTH_MODE="token", RAY_AUTH_TOKEN_PATH=str(token))
    return env


def _holder(folder: Path):
    """The process with a file in ``folder`` open (a trial's worker keeps its TensorBoard file open)."""
    import psutil

    for p in psutil.process_iter():
        with contextlib.suppress(psutil.Error):
            if any(f.path.startswith(f"{folder}/") for f in p.open_files()):
                return p
    return None


@pytest.mark.cluster
def test_a_sweep_on_a_two_node_cluster_lands_under_its_out_and_a_killed_worker_resumes(tmp_path):
    """Two short jobs against the head of a two-node cluster, from another working directory with a
    relative --out: both run folders land under that --out (not the workers' working directory),
    the job whose worker is killed mid-run is retried and resumes from its checkpoint, and it ends
    where an uninterrupted run ends. The nodes have no access to this checkout (no PYTHONPATH, run
    from /): the driver ships its code."""
    preset = _preset(tmp_path, steps=240)
    ray_env = _ray_env(tmp_path)
    (tmp_path / "elsewhere").mkdir()
    root = tmp_path / "elsewhere" / "sw"
    with _cluster(ray_env) as (address, _):
        env = {**ray_env, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
        proc = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "comat.cli",
                "sweep",
                "--address",
                address,
                "--preset",
                str(preset),
                "--algos",
                "comat",
                "--tasks",
                "pcp",
                "--seeds",
                "0",
                "1",
                "--no-eval",
                "--out",
                "sw",
            ],
            cwd=tmp_path / "elsewhere",
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        killed, deadline = None, time.monotonic() + 400
        while killed is None and proc.poll() is None and time.monotonic() < deadline:
            for seed in (0, 1):
                run = root / f"comat_pcp_s{seed}"
                worker = _holder(run) if (run / "checkpoint.pt").is_file() else None
                if worker is not None and not (run / "summary.json").exists():
                    worker.kill()
                    killed = run
                    break
            time.sleep(0.2)
        stdout, stderr = proc.communicate(timeout=600)
    assert killed is not None, stdout + stderr[-3000:]
    assert proc.returncode == 0, stdout + stderr[-3000:]
    assert f"RETRY comat/pcp/s{killed.name[-1]}" in stdout, stdout
    for seed in (0, 1):
        summary = json.loads((root / f"comat_pcp_s{seed}" / "summary.json").read_text())
        assert summary["env_steps"] == 240
    sittings = yaml.safe_load((killed / "config.yaml").read_text())
    assert sittings["resumed_at_env_steps"] > 0 and len(sittings["earlier_sittings"]) == 1  # resumed, not restarted
    swept = load_checkpoint(killed / "checkpoint.pt")
    straight = _straight(preset, "comat", int(killed.name[-1]), tmp_path / "straight")
    assert_same(swept["trainer"], straight["trainer"], "trainer")
    assert not (Path("/") / "sw").exists()


@pytest.mark.cluster
def test_ray_job_submit_runs_a_sweep_on_the_cluster(tmp_path):
    """The README's cluster recipe: ``ray job submit -- comat sweep --address auto ...`` (the driver
    runs on the cluster, inside a job with a runtime env of its own); both runs land under --out."""
    preset = _preset(tmp_path)
    ray_env = _ray_env(tmp_path)
    ray = shutil.which("ray", path=str(Path(sys.executable).parent)) or shutil.which("ray")
    root = tmp_path / "sw"
    with _cluster(ray_env, nodes=1, dashboard=True) as (_, dashboard):
        job_env = json.dumps({"env_vars": {"PYTHONPATH": str(ROOT)}})  # the job's driver imports this checkout
        done = subprocess.run(
            [
                ray,
                "job",
                "submit",
                "--address",
                dashboard,
                "--runtime-env-json",
                job_env,
                "--",
                str(Path(sys.executable).with_name("comat")),
                "sweep",
                "--address",
                "auto",
                "--preset",
                str(preset),
                "--algos",
                "comat",
                "--tasks",
                "pcp",
                "--seeds",
                "0",
                "1",
                "--no-eval",
                "--out",
                str(root),
            ],
            check=False,
            env=ray_env,
            capture_output=True,
            text=True,
            timeout=600,
        )
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-2000:]
    assert "2 of 2 jobs finished" in done.stdout
    for seed in (0, 1):
        assert json.loads((root / f"comat_pcp_s{seed}" / "summary.json").read_text())["env_steps"] == 12
