"""What a training run may use of this machine, and who else is training on it.

A run reads the CPUs it may use from its affinity (``taskset``, a container's cpuset, a Ray
worker's assignment where Ray pins it) and says so in ``comat train``'s first line. Every running
``comat train`` leaves a small file in a per-user folder of the temporary directory while it runs
(:class:`RunRegistry`); a run that finds others there, or a machine whose load is above its CPU
count, warns and names the cause: side-by-side runs share the CPUs, and each gets about its share.
Waiting torch workers spin briefly, then sleep (:func:`set_thread_waiting`, before torch loads,
unless the user chose): spinning without end, two runs on one machine steal each other's cores;
sleeping at once, a lone run's PPO update waits on every operation for its workers to wake
(benchmarks/side_by_side.py and results/speed/update_time.py measure both).
"""

from __future__ import annotations

import json
import os
import tempfile
import time
from pathlib import Path

__all__ = ["SPIN_COUNT", "RunRegistry", "busy_warning", "set_thread_waiting", "usable_cpus"]

SPIN_COUNT = 10_000
"""How long an idle torch worker thread spins before it sleeps (libgomp's ``GOMP_SPINCOUNT``, the
OpenMP runtime of torch's Linux wheels). Measured on the 2-core Xeon (issue 48): COMAT's PPO update
on one PCP rollout takes 2.62 s with workers that sleep at once (``OMP_WAIT_POLICY=PASSIVE``), 2.1 s
at 3,000 spins, 1.69 s at 10,000 and 1.50 s at libgomp's own 300,000. Two runs that both spin
10,000 times each keep 0.54 of a lone run's rate (0.28 at 300,000; the shared-machine target is
0.40), so a run that finds others training sleeps at once (:func:`set_thread_waiting`): two runs
started together then keep 0.78 and 0.71 (benchmarks/side_by_side.py)."""


def set_thread_waiting(environ=os.environ, others_training: bool = False) -> None:
    """How torch's idle worker threads wait, set in ``environ`` before torch loads: spin
    :data:`SPIN_COUNT` times, then sleep; sleep at once where ``others_training`` (other comat
    trainings already run on this machine: spinning threads would take their cores) and in OpenMP
    runtimes without ``GOMP_SPINCOUNT`` (``OMP_WAIT_POLICY=PASSIVE``). A user's own
    ``OMP_WAIT_POLICY`` or ``GOMP_SPINCOUNT`` is kept as it is."""
    if "OMP_WAIT_POLICY" in environ or "GOMP_SPINCOUNT" in environ:
        return
    environ["OMP_WAIT_POLICY"] = "PASSIVE"
    if not others_training:
        environ["GOMP_SPINCOUNT"] = str(SPIN_COUNT)  # read by libgomp in place of PASSIVE's 0


def usable_cpus() -> int:
    """CPUs this process may run on (its affinity; the CPU count where the OS has no affinity)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # macOS, Windows
        return os.cpu_count() or 1


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's process: alive
        return True
    return True


class RunRegistry:
    """The comat trainings running on this machine: ``with RunRegistry(out) as others:`` registers
    this one for the block's duration and gives the others (their pid, run folder, threads, start)."""

    def __init__(self, out, threads: int, root: Path | None = None) -> None:
        uid = os.getuid() if hasattr(os, "getuid") else "user"
        self.root = Path(root) if root is not None else Path(tempfile.gettempdir()) / f"comat-runs-{uid}"
        self.entry = {"pid": os.getpid(), "out": str(out), "threads": int(threads), "started": time.time()}
        self.path = self.root / f"{os.getpid()}.json"

    def others(self) -> list[dict]:
        """Live runs other than this one (files of ended runs are removed)."""
        found = []
        for path in sorted(self.root.glob("*.json")) if self.root.is_dir() else []:
            try:
                entry = json.loads(path.read_text())
                pid = int(entry["pid"])
            except (OSError, ValueError, KeyError, TypeError):
                continue
            if pid == os.getpid():
                continue
            if _alive(pid):
                found.append(entry)
            else:
                path.unlink(missing_ok=True)  # a run that was killed
        return found

    def announce(self) -> None:
        """Write this run's entry (a read-only temporary directory: the run goes on unregistered)."""
        try:
            self.root.mkdir(parents=True, exist_ok=True)
            self.path.write_text(json.dumps(self.entry))
        except OSError:
            pass

    def __enter__(self) -> list[dict]:
        others = self.others()
        self.announce()
        return others

    def __exit__(self, *exc) -> None:
        self.path.unlink(missing_ok=True)


def busy_warning(others: list[dict], cpus: int) -> str | None:
    """A warning naming why this run will be slower than alone, or None."""
    parts = []
    if others:
        who = ", ".join(f"pid {o['pid']} ({o['out']})" for o in others[:3]) + (" ..." if len(others) > 3 else "")
        parts.append(
            f"{len(others)} other comat training(s) on this machine: {who}; the {cpus} CPU(s) are shared, "
            f"so expect about 1/{len(others) + 1} of this run's speed alone (run grids with comat sweep "
            "--jobs, which gives each run its own cores)"
        )
    try:
        load = os.getloadavg()[0]
    except (AttributeError, OSError):
        load = 0.0
    if load > cpus + 0.5 and not others:
        parts.append(f"the machine is busy (load average {load:.1f} on {cpus} CPU(s)): this run will be slower")
    return "warning: " + "; ".join(parts) if parts else None
