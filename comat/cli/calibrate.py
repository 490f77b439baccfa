"""``comat calibrate LOGS... --out PROFILE.yaml``: fit the reality layer to calibration logs.

Reads ``calib_<experiment>.npy`` logs (:mod:`comat.calibration.experiments`; one or many runs),
fits each parameter the logs identify (:mod:`comat.calibration.fit`), prints a table (parameter,
estimate, 95 % interval over robots, robots and runs used, a note) and writes a profile that
``comat train ... reality=PROFILE.yaml`` and ``comat eval --reality PROFILE.yaml`` take: the
layer at ``off`` with the identified fields set (what the logs cannot show stays off and is
listed under ``not_identified``). ``--simulate REALITY`` instead writes the logs of the
experiments run in comat with the layer at a level, profile or field mapping: the known truth a
fit can be checked against.
"""

from __future__ import annotations

import argparse
import io
import json
import math
from pathlib import Path

__all__ = ["add_calibrate_parser"]


def _fmt(v) -> str:
    if v is None:
        return "—"
    if isinstance(v, int):
        return str(v)
    return "nan" if math.isnan(v) else f"{v:.4g}"


def _cmd(args: argparse.Namespace) -> int:
    import yaml

    from comat.files import new_outputs, write_atomic

    if args.simulate is not None:
        import numpy as np

        from comat.calibration.experiments import EXPERIMENTS, simulate

        reality = args.simulate
        if reality.startswith("{"):
            reality = json.loads(reality)
        names = [f"calib_{e}.npy" for e in EXPERIMENTS]
        with new_outputs(args.out, names, force=args.force) as out:
            for e in EXPERIMENTS:
                log = simulate(e, reality, n=args.robots, seed=args.seed)
                buf_path = out / f"calib_{e}.npy"
                buf = io.BytesIO()
                np.save(buf, log)
                write_atomic(buf_path, buf.getvalue())
                print(f"wrote {buf_path} ({log.shape[0]} iterations, {log.shape[1]} robots)")
        return 0
    from comat.calibration.fit import fit_logs, profile_fields
    from comat.reality import RealityConfig

    if not args.logs:
        raise ValueError("LOGS: give at least one calibration log (calib_steps.npy, calib_still.npy, calib_ramp.npy, calib_spin.npy)")
    fit = fit_logs(args.logs)
    fields = profile_fields(fit)
    config = RealityConfig(**fields)  # the profile is a valid layer before anything is written
    print(f"{'parameter':<24}{'estimate':>10}{'95 % interval':>22}{'robots':>8}{'runs':>6}  note")
    for p in fit["parameters"]:
        interval = "" if p["lo"] is None else f"[{_fmt(p['lo'])}, {_fmt(p['hi'])}]"
        print(f"{p['name']:<24}{_fmt(p['estimate']):>10}{interval:>22}{p['robots']:>8}{p['runs']:>6}  {p['note']}")
    import dataclasses

    profile = {
        "reality": {k: v for k, v in dataclasses.asdict(config).items() if k in fields},
        "not_identified": [p["name"] for p in fit["parameters"] if p["estimate"] is None],
        "fit": [{k: v for k, v in p.items()} for p in fit["parameters"]],
        "logs": [str(Path(p)) for p in args.logs],
    }
    out = Path(args.out)
    if out.suffix not in (".yaml", ".yml"):
        raise ValueError(f"--out must be a .yaml file (the profile), got {args.out!r}")
    with new_outputs(out.parent, [out.name], force=args.force):
        write_atomic(out, yaml.safe_dump(json.loads(json.dumps(profile)), sort_keys=False))
    print(f"wrote {out}: train with `comat train ... reality={out}`, evaluate with `comat eval --reality {out}`")
    return 0


def add_calibrate_parser(subparsers) -> argparse.ArgumentParser:
    """``comat calibrate`` on the top-level sub-parsers."""
    from comat.cli.args import add_force

    p = subparsers.add_parser(
        "calibrate", help="fit the reality layer to calibration logs (calib_steps.npy, calib_still.npy, calib_ramp.npy, calib_spin.npy)",
        description=__doc__.split("\n\n")[1].replace("``", "'").replace(":mod:", ""))
    p.add_argument("logs", nargs="*", metavar="LOGS", help="calibration logs calib_<experiment>[.<run>].npy")
    p.add_argument("--out", required=True, help="the profile to write (PROFILE.yaml); with --simulate, a folder")
    p.add_argument("--simulate", default=None, metavar="REALITY",
                   help="write the experiments' logs from comat's simulator at this layer (a level, a profile "
                   "PROFILE.yaml or a JSON mapping of fields) into the folder --out, instead of fitting")
    p.add_argument("--robots", type=int, default=4, help="robots of a simulated run (default: %(default)s)")
    p.add_argument("--seed", type=int, default=0, help="seed of a simulated run (default: %(default)s)")
    add_force(p)
    p.set_defaults(func=_cmd)
    return p

