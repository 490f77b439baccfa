"""Robotarium calibration folders: ``export_calibration`` and ``check_calibration``.

``comat export --calibration OUT`` writes one flat submission folder per experiment of
:data:`comat.calibration.schedule.EXPERIMENTS` (``OUT/steps``, ``OUT/still``, ``OUT/ramp``, ``OUT/spin``): ``main.py``
(``sim2real/templates/calibration_main.py``, its first line naming the experiment, what it measures
and how long it runs), ``calibration_schedule.py``
(``comat/calibration/schedule.py``, verbatim: numpy only) and ``submission_config.py``
(``CONFIG``: experiment, robots, iterations, what it measures, how long it runs). The same rules
as every export: ``.py`` files only, numpy and rps imports, no folders, atomically written.
Upload a folder, download the ``calib_<experiment>.npy`` the run saves, fit with ``comat
calibrate``. ``comat export --check OUT/steps`` runs it under rps and fits the log it saves: the
simulator has no delay, noise or motor model, so the fit must find none.
"""

from __future__ import annotations

import pprint
import shutil
import tempfile
from pathlib import Path

from comat.calibration import schedule as schedule_module
from comat.calibration.experiments import load_log
from comat.calibration.fit import fit_ramp, fit_spin, fit_steps, fit_still
from comat.calibration.schedule import CONTROL_DT_S, EXPERIMENTS, MAX_ROBOTS
from comat.constants import STARTUP_DRIVE_S  # the drive to the lanes, in the duration each folder declares
from sim2real.check import run_rps

__all__ = ["CALIBRATION_FILES", "MEASURES", "check_calibration", "export_calibration", "is_calibration"]

CALIBRATION_FILES = ("main.py", "calibration_schedule.py", "rps_compat.py", "submission_config.py")
MEASURES = {
    "steps": "forward-speed steps 0 -> 1/2 -> full -> 0 and back: delay from command to observed motion (pose + "
    "command), wheel lag and slew, reachable speed, wheel gain difference (heading drift per metre)",
    "still": "robots standing still: pose noise (x, y, theta) and the share of repeated poses (holds)",
    "ramp": "forward speed ramped slowly from standstill to 40 % of the top speed and back: the dead zone (the "
    "wheel speed below which a robot does not move)",
    "spin": "turn-rate steps 0 -> 1/2 -> 95 % of 3.64 rad/s -> 0 and back, turning in place: delay, lag, turn-rate "
    "gain, reachable wheel speed, wheel gain difference (the circle the robot's centre draws)",
}
_TEMPLATE = Path(__file__).parent / "templates" / "calibration_main.py"


def export_calibration(out_dir, robots: int = MAX_ROBOTS) -> list[Path]:
    """Write one folder per experiment under ``out_dir`` (which must not exist); their paths."""
    out = Path(out_dir)
    if out.exists():
        raise FileExistsError(f"--calibration {str(out)!r} already exists; choose a new folder")
    if isinstance(robots, bool) or not isinstance(robots, int) or not 1 <= robots <= MAX_ROBOTS:
        raise ValueError(f"--robots must be an integer in [1, {MAX_ROBOTS}] (lanes 0.4 m apart), got {robots!r}")
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f"{out.name}.tmp-", dir=out.parent))
    try:
        for experiment, iterations in EXPERIMENTS.items():
            folder = tmp / experiment
            folder.mkdir()
            loop_s = round(iterations * CONTROL_DT_S, 1)
            duration = round(loop_s + STARTUP_DRIVE_S)  # what the experiment form must be told
            # The template with its first line naming this experiment, what it measures and its length.
            body = _TEMPLATE.read_text().split("\n", 1)[1]
            (folder / "main.py").write_text(
                f'"""Calibration run on the Robotarium, experiment {experiment!r}: {iterations} iterations, '
                f"{loop_s} s, after the robots' drive to their lanes: declare {duration} s.\n"
                f"Measures: {MEASURES[experiment]}.\n" + body
            )
            shutil.copyfile(schedule_module.__file__, folder / "calibration_schedule.py")
            shutil.copyfile(_TEMPLATE.parent / "rps_compat.py", folder / "rps_compat.py")
            config = {
                "kind": "calibration",
                "experiment": experiment,
                "robots": robots,
                "iterations": iterations,
                "loop_s": loop_s,
                "duration_s": duration,
                "measures": MEASURES[experiment],
            }
            (folder / "submission_config.py").write_text(
                f'"""Calibration experiment {experiment!r} (comat export --calibration)."""\n\nCONFIG = '
                + pprint.pformat(config, sort_dicts=False, width=100)
                + "\n"
            )
        tmp.rename(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return [out / e for e in EXPERIMENTS]


def is_calibration(folder) -> bool:
    """Whether ``folder`` is a calibration folder (its CONFIG says ``kind: calibration``)."""
    path = Path(folder) / "submission_config.py"
    return path.is_file() and "'kind': 'calibration'" in path.read_text()


def check_calibration(folder, timeout_s: float = 1800.0, rps_path=None) -> dict:
    """Run the folder under rps (:func:`sim2real.check.run_rps`) and fit the log it saved:
    ``{"rps": its COMAT_RESULT, "fit": per-robot estimates}``. The run happens in a copy of the folder,
    so the folder a user uploads stays as exported; the log is kept beside it, as
    ``calib_<experiment>.rps-<folder name>.npy`` (a log ``comat calibrate`` reads; ``result["rps"]["log"]``
    names that file)."""

    folder = Path(folder)
    missing = [f for f in CALIBRATION_FILES if not (folder / f).is_file()]
    if missing:
        raise FileNotFoundError(f"{str(folder)!r} is not a calibration folder: missing {missing}")
    with tempfile.TemporaryDirectory(prefix="comat-calibration-check-") as tmp:
        copy = Path(tmp) / folder.name
        shutil.copytree(folder, copy)
        result = run_rps(copy, timeout_s, rps_path)
        log_name = Path(result["log"])
        kept = folder.parent / f"{log_name.stem}.rps-{folder.name}{log_name.suffix}"
        shutil.move(str(copy / result["log"]), kept)
    result["log"] = str(kept)
    experiment, log = load_log(kept)
    fit = {"steps": fit_steps, "still": fit_still, "ramp": fit_ramp, "spin": fit_spin}[experiment](log)
    return {"rps": result, "fit": fit}
