"""Every export under the Robotarium server's Pythons: ``python -m sim2real.server_pythons`` (``make test-server``).

The Robotarium runs a submission's ``main.py`` on its own Python, not comat's. Two servers are
documented, and each gets a virtual environment of its own, built from pyenv's interpreters:

==========  ==================================================  ====================================
Python      packages                                            source
==========  ==================================================  ====================================
3.8         numpy 1.23.5, scipy 1.10.1, matplotlib 3.7.2,       the Robotarium guide's Appendix A
            cvxopt 1.3.2, the PyPI rps                          (Nov 2024: Ubuntu 20.04, Python 3.8);
                                                                CASH-MARBLER's Jan 2025 server logs
3.10        numpy 2.2.6, scipy 1.15.3, matplotlib 3.10.8,       V2's ``libraries.txt`` (2026; its
            cvxopt 1.3.2, the PyPI rps                          backports say Python 3.10)
==========  ==================================================  ====================================

The guide lists no cvxopt: 1.3.2, V2's, is pinned on both (cp38 wheels exist), since both rps
generations import it. The PyPI rps is the requirement of comat's ``robotarium`` extra (the legacy
2020 simulator; V2 is not on PyPI and runs through ``COMAT_RPS_V2`` in the export tests).

For every registered task this exports the scripted policy and each shipped COMAT policy of that
task (``pretrained:NAME``; export takes COMAT only), plus the four calibration folders, and runs
each folder's ``main.py`` to its end under both Pythons, figures off: the run passes when it exits
0, rps counts no boundary, collision or actuator error, and the episode reached its end (finished,
or all its steps). Each scripted folder also runs 2 env steps with its figure on (Agg backend),
the drawing code the server runs. Prints a table task × policy × Python (ok or FAIL, seconds);
exit 1 on any failure.

Interpreters: ``$PYTHON38`` / ``$PYTHON310``, else ``pyenv prefix 3.8`` / ``3.10``; a missing one
is a one-line error (exit 2). The environments live in ``.venv-py38`` / ``.venv-py310`` of the
working folder and are rebuilt only when their requirements change.
"""

from __future__ import annotations

import argparse
import importlib.metadata
import os
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

__all__ = ["SERVERS", "Server", "ServerPythonError", "find_python", "main", "rps_requirement"]


class ServerPythonError(RuntimeError):
    """A server's interpreter or environment could not be found or built (one line)."""


@dataclass(frozen=True)
class Server:
    """One Robotarium server's Python: its version, where the interpreter comes from and what it has."""

    version: str
    """``major.minor``."""
    env_var: str
    """Environment variable naming the interpreter (else pyenv's)."""
    packages: tuple[str, ...]
    """Pinned requirements besides the PyPI rps."""

    @property
    def venv(self) -> str:
        """Folder of its virtual environment: ``.venv-py38``."""
        return ".venv-py" + self.version.replace(".", "")


SERVERS = (
    Server("3.8", "PYTHON38", ("numpy==1.23.5", "scipy==1.10.1", "matplotlib==3.7.2", "cvxopt==1.3.2")),
    Server("3.10", "PYTHON310", ("numpy==2.2.6", "scipy==1.15.3", "matplotlib==3.10.8", "cvxopt==1.3.2")),
)
FIGURE_STEPS = 2
"""Env steps of the figure-on run of each scripted folder (paced in real time: about 2 s for PCP)."""
TEAM_SET, TEAM_INDEX = "test", 3
"""The team every folder is exported for, ``test:3`` (4 robots in PCP and HMT, 8 in arctic)."""
SEED = 1
"""Seed of the exported start poses and layouts."""


def rps_requirement() -> str:
    """The PyPI rps as comat's ``robotarium`` extra requires it (``robotarium-python-simulator==0.0.0``)."""
    for req in importlib.metadata.requires("comat") or []:
        if req.startswith("robotarium-python-simulator"):
            return req.split(";")[0].strip()
    raise ServerPythonError("comat's metadata names no robotarium-python-simulator (the robotarium extra)")


def find_python(server: Server) -> str:
    """The interpreter of ``server``: ``$PYTHON38`` (etc.), else pyenv's; checked to be that version."""
    path = os.environ.get(server.env_var)
    if path and not Path(path).is_file():
        raise ServerPythonError(f"{server.env_var}={path!r} is not a file (expected a python{server.version})")
    if not path:
        try:
            proc = subprocess.run(["pyenv", "prefix", server.version], capture_output=True, text=True, check=False)
            prefix = proc.stdout.strip() if proc.returncode == 0 else ""
        except FileNotFoundError:  # no pyenv
            prefix = ""
        path = str(Path(prefix) / "bin" / f"python{server.version}") if prefix else ""
        if not path or not Path(path).is_file():
            raise ServerPythonError(
                f"Python {server.version} not found: set {server.env_var} to a python{server.version} or install "
                f"it with pyenv (pyenv install {server.version}); pyenv prefix {server.version} gave none"
            )
    got = subprocess.run(
        [path, "-c", "import sys; print('%d.%d' % sys.version_info[:2])"], capture_output=True, text=True, check=False
    ).stdout.strip()
    if got != server.version:
        raise ServerPythonError(f"{server.env_var}={path!r} is Python {got or '?'}, expected {server.version}")
    return path


def ensure_venv(server: Server, root: Path) -> Path:
    """``root/.venv-pyXY`` with ``server``'s packages and the PyPI rps (built once per requirement set);
    its python."""
    venv = root / server.venv
    python = venv / "bin" / "python"
    interpreter = find_python(server)
    wanted = "\n".join([interpreter, *server.packages, rps_requirement()]) + "\n"
    stamp = venv / ".installed"
    if stamp.is_file() and stamp.read_text() == wanted and python.is_file():
        return python
    t0 = time.perf_counter()
    subprocess.run([interpreter, "-m", "venv", "--clear", str(venv)], check=True)
    pip = [str(python), "-m", "pip", "install", "-q", "--disable-pip-version-check", "--only-binary=:all:"]
    proc = subprocess.run(
        [*pip, *server.packages, rps_requirement()], capture_output=True, text=True, check=False
    )  # quiet unless it fails (the index prints a warning per package)
    if proc.returncode != 0:
        raise ServerPythonError(
            f"pip could not install {list(server.packages)} into {venv} (Python {server.version}): "
            + (proc.stderr.strip().splitlines() or ["no output"])[-1]
        )
    stamp.write_text(wanted)
    print(f"built {venv} (Python {server.version}) in {time.perf_counter() - t0:.0f} s", flush=True)
    return python


def _exports(out: Path) -> list[tuple[str, str, Path]]:
    """(task, policy label, folder) of every export this check runs."""
    from comat.envs.base import resolve_coalitions
    from comat.rl import PRETRAINED, load_trained, pretrained_path
    from comat.tasks import task_names
    from sim2real.calibration import export_calibration
    from sim2real.export import export_submission

    shipped = {}
    for name in PRETRAINED:
        data = load_trained(pretrained_path(name))
        if data["algo"] == "comat":
            shipped.setdefault(data["task"], []).append(name)
    rows = []
    for task in task_names():
        team = resolve_coalitions(TEAM_SET, task)[TEAM_INDEX]
        rows.append(
            (task, "heuristic", export_submission("heuristic", task, team, out / f"{task}-heuristic", seed=SEED))
        )
        for name in shipped.get(task, []):
            folder = export_submission(str(pretrained_path(name)), task, team, out / f"{task}-{name}", seed=SEED)
            rows.append((task, f"pretrained:{name}", folder))
    for folder in export_calibration(out / "calibration"):
        rows.append(("calibration", folder.name, folder))
    return rows


def _run(folder: Path, copy: Path, python: Path, horizon: int | None, figure: bool) -> tuple[bool, float, str]:
    """Run ``folder``'s main.py in ``copy`` (a fresh copy) under ``python``: (passed, seconds, what
    was wrong, or how far it ran)."""
    from sim2real.check import CheckError, run_rps

    shutil.copytree(folder, copy)
    t0 = time.perf_counter()
    try:
        result = run_rps(
            copy, timeout_s=900, show_figure=figure, max_steps=FIGURE_STEPS if figure else None, python=str(python)
        )
    except CheckError as err:
        return False, time.perf_counter() - t0, str(err)
    seconds = time.perf_counter() - t0
    errors = {k: v for k, v in result.get("rps_errors", {}).items() if v}
    if errors:
        return False, seconds, f"rps errors {errors}"
    if horizon is None:  # a calibration folder: its schedule ran to the end
        return True, seconds, f"{result['iterations']} iterations"
    wanted = FIGURE_STEPS if figure else horizon
    if not result["finished"] and result["steps"] < wanted:
        return False, seconds, f"stopped after {result['steps']} of {wanted} steps"
    if figure and result.get("figure_artists", 0) <= 0:
        return False, seconds, "drew no task artists"
    return True, seconds, f"{result['steps']} steps"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m sim2real.server_pythons", description=__doc__.splitlines()[0])
    parser.add_argument("--venvs", default=".", help="folder of .venv-py38 and .venv-py310 (default: %(default)s)")
    parser.add_argument(
        "--jobs", type=int, default=min(4, os.cpu_count() or 1), help="main.py runs at once (default: %(default)s)"
    )
    args = parser.parse_args(argv)
    if args.jobs < 1:
        parser.error(f"--jobs must be >= 1, got {args.jobs}")
    t_start = time.perf_counter()
    from comat.tasks import task_entry

    try:
        pythons = {s.version: ensure_venv(s, Path(args.venvs).resolve()) for s in SERVERS}
    except ServerPythonError as err:
        print(f"server-pythons: error: {err}", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory(prefix="comat-server-pythons-") as tmp:
        t0 = time.perf_counter()
        rows = _exports(Path(tmp) / "exports")
        print(f"exported {len(rows)} folders in {time.perf_counter() - t0:.0f} s", flush=True)
        jobs = []  # (task, policy label, Python, figure on, folder, its copy for this run, python, horizon)
        for task, label, folder in rows:
            horizon = None if task == "calibration" else task_entry(task).logic().horizon
            for version, python in pythons.items():
                for figure in (False, True) if label == "heuristic" else (False,):
                    copy = Path(tmp) / f"py{version}{'-figure' if figure else ''}" / f"{task}-{label.replace(':', '-')}"
                    jobs.append((task, label, version, figure, folder, copy, python, horizon))
        os.environ.update(OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")  # one core per run: --jobs runs at once
        with ThreadPoolExecutor(args.jobs) as pool:
            results = list(pool.map(lambda j: _run(*j[4:8], j[3]), jobs))
    cells = {(j[0], j[1], j[2], j[3]): r for j, r in zip(jobs, results)}
    versions = list(pythons)
    head = f"{'task':<12}{'policy':<22}" + "".join(f"{'Python ' + v:>17}{v + ' figure':>15}" for v in versions)
    print("\n" + head)
    for task, label, _ in rows:
        line = f"{task:<12}{label:<22}"
        for v in versions:
            for figure, width in ((False, 17), (True, 15)):
                cell = cells.get((task, label, v, figure))
                text = "-" if cell is None else f"{'ok' if cell[0] else 'FAIL'} {cell[1]:5.1f} s"
                line += f"{text:>{width}}"
        print(line)
    failed = [(key, r) for key, r in cells.items() if not r[0]]
    for (task, label, v, figure), r in failed:
        print(f"FAIL {task} {label} under Python {v}{' (figure on)' if figure else ''}: {r[2]}")
    print(
        f"{len(cells) - len(failed)}/{len(cells)} runs passed ({len(rows)} folders x {len(versions)} Pythons, "
        f"figure runs included) in {time.perf_counter() - t_start:.0f} s"
    )
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
