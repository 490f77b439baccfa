"""``comat calibrate LOGS... --out PROFILE.yaml``: fit the reality layer to calibration logs.

Reads ``calib_<experiment>.npy`` logs (:mod:`comat.calibration.experiments`; one or many runs) and
policy runs' ``comat_run.npy`` logs (:mod:`comat.calibration.from_runs`: every run is also a
calibration), fits each parameter the logs identify (:mod:`comat.calibration.fit`), prints a table
(parameter, estimate, its interval and what kind it is: over robots for what each robot has on its
own, over blocks of ticks for what the team shares, :mod:`comat.calibration.intervals`; robots and
runs used; with ``--truth``, the known value; a note) and writes a profile, with a comment header
saying what each field it sets means, that ``comat train ... reality=PROFILE.yaml`` and
``comat eval --reality PROFILE.yaml`` take: the layer at ``nominal`` with the identified fields set
(what the logs cannot show keeps nominal's value, and ``not_identified`` says so field by field).
``--simulate REALITY`` instead writes the logs of the experiments run in comat with the layer at a
level, profile or field mapping, and the layer's resolved fields as ``truth.yaml`` beside them: the
known truth a fit is checked against (``--truth``).
"""

from __future__ import annotations

import argparse
import dataclasses
import io
import json
import math
import textwrap
from pathlib import Path

__all__ = ["add_calibrate_parser"]


def _table(parameters: list[dict], truth: dict[str, str] | None) -> str:
    """The fit as a table with columns sized to their cells: an interval says what kind it is
    (:data:`comat.calibration.intervals.KINDS`)."""
    from comat.calibration.intervals import KINDS

    head = ["parameter", "estimate", "interval", "kind", *(["truth"] if truth else []), "robots", "runs", "note"]
    rows = []
    for p in parameters:
        interval = "" if p["lo"] is None else f"[{_fmt(p['lo'])}, {_fmt(p['hi'])}]"
        rows.append(
            [
                p["name"],
                _fmt(p["estimate"]),
                interval,
                KINDS.get(p.get("interval"), ""),
                *([truth.get(p["name"], "")] if truth else []),
                str(p["robots"]),
                str(p["runs"]),
                p["note"],
            ]
        )
    widths = [max(len(r[k]) for r in [head, *rows]) for k in range(len(head) - 1)]
    right = {1, 2, len(head) - 3, len(head) - 2}  # numbers right-aligned
    return "\n".join(
        "  ".join(c.rjust(w) if k in right else c.ljust(w) for k, (c, w) in enumerate(zip(r, widths))) + "  " + r[-1]
        for r in [head, *rows]
    )


def _header(fields: dict, logs: list[str]) -> str:
    """The profile's comment header: where it comes from and what each field it sets means."""
    from comat.reality.config import field_docs

    docs = field_docs()
    lines = textwrap.wrap(
        f"comat calibrate: a reality profile fitted to {len(logs)} calibration log(s): the "
        "layer at 'nominal' with the fields below set (fit: the estimates behind them; not_identified: "
        "the fields the logs cannot show, which keep nominal's values). The fields:",
        100,
    ) + [""]
    for name in fields:
        if name in docs and name != "level":
            lines += textwrap.wrap(f"{name}: {docs[name]}", 100, subsequent_indent="    ")
    return "".join(f"# {line}\n" if line else "#\n" for line in lines)


def _fmt(v) -> str:
    if v is None:
        return "—"
    if isinstance(v, int):
        return str(v)
    return "nan" if math.isnan(v) else f"{v:.4g}"


def _check_profile(value) -> None:
    """A profile file given (``--simulate``, ``--truth``) that ``comat calibrate`` fitted: its intervals
    of the present kinds, else a one-line error before anything is written
    (:func:`comat.calibration.intervals.read_fit`)."""
    import yaml

    if not (isinstance(value, str) and value.endswith((".yaml", ".yml")) and Path(value).is_file()):
        return  # a level, a mapping, or a missing file (resolve_reality says so)
    try:
        data = yaml.safe_load(Path(value).read_text())
    except yaml.YAMLError:
        return  # not YAML: resolve_reality says so in one line
    if isinstance(data, dict) and "fit" in data:
        from comat.calibration.intervals import read_fit

        read_fit(value)


def _cmd(args: argparse.Namespace) -> int:
    import yaml

    from comat.files import new_outputs, write_atomic

    if args.simulate is not None:
        import numpy as np

        from comat.calibration.experiments import EXPERIMENTS, simulate
        from comat.reality import resolve_reality

        reality = args.simulate
        if reality.startswith("{"):
            reality = json.loads(reality)
        _check_profile(reality)
        names = [f"calib_{e}.npy" for e in EXPERIMENTS]
        truth = dataclasses.asdict(resolve_reality(reality))
        with new_outputs(args.out, [*names, "truth.yaml"], force=args.force) as out:
            for e in EXPERIMENTS:
                log = simulate(e, reality, n=args.robots, seed=args.seed)
                buf_path = out / f"calib_{e}.npy"
                buf = io.BytesIO()
                np.save(buf, log)
                write_atomic(buf_path, buf.getvalue())
                print(f"wrote {buf_path} ({log.shape[0]} iterations, {log.shape[1]} robots)")
            write_atomic(out / "truth.yaml", yaml.safe_dump({"reality": truth}, sort_keys=False))
        print(
            f"wrote {out / 'truth.yaml'} (the layer the logs were simulated at); fit them with: comat calibrate "
            f"{out}/calib_*.npy --truth {out / 'truth.yaml'} --out PROFILE.yaml"
        )
        return 0
    from comat.calibration.profile import fit_logs, profile_fields, truth_of, unidentified_fields
    from comat.reality import RealityConfig, resolve_reality
    from comat.reality.config import PROFILE_FORMAT

    if not args.logs:
        raise ValueError(
            "LOGS: give at least one calibration log (calib_steps.npy, calib_still.npy, calib_ramp.npy, "
            "calib_spin.npy) or a run's comat_run.npy"
        )
    _check_profile(args.truth)
    truth = None if args.truth is None else truth_of(resolve_reality(args.truth))
    fit = fit_logs(args.logs)
    fields = profile_fields(fit)
    config = RealityConfig(**fields)  # the profile is a valid layer before anything is written
    print(_table(fit["parameters"], truth))
    profile = {
        "format": PROFILE_FORMAT,
        "reality": {k: v for k, v in dataclasses.asdict(config).items() if k in fields},
        "not_identified": unidentified_fields(fields, {p["name"]: p["note"] for p in fit["parameters"]}),
        "fit": [{k: v for k, v in p.items()} for p in fit["parameters"]],
        "logs": [str(Path(p)) for p in args.logs],
    }
    out = Path(args.out)
    if out.suffix not in (".yaml", ".yml"):
        raise ValueError(f"--out must be a .yaml file (the profile), got {args.out!r}")
    with new_outputs(out.parent, [out.name], force=args.force):
        write_atomic(
            out,
            _header(profile["reality"], args.logs) + yaml.safe_dump(json.loads(json.dumps(profile)), sort_keys=False),
        )
    print(f"wrote {out}: train with `comat train ... reality={out}`, evaluate with `comat eval --reality {out}`")
    return 0


def add_calibrate_parser(subparsers) -> argparse.ArgumentParser:
    """``comat calibrate`` on the top-level sub-parsers."""
    from comat.cli.args import add_force

    p = subparsers.add_parser(
        "calibrate",
        help="fit the reality layer to calibration logs "
        "(calib_steps.npy, calib_still.npy, calib_ramp.npy, calib_spin.npy) and runs' logs (comat_run.npy)",
        description=__doc__.split("\n\n")[1].replace("``", "'").replace(":mod:", ""),
    )
    p.add_argument(
        "logs",
        nargs="*",
        metavar="LOGS",
        help="calibration logs calib_<experiment>[.<run>].npy, and policy runs' logs comat_run.npy (the "
        "meta file beside each): a run identifies the delay, the lag, the speed and turn gains and the holds",
    )
    p.add_argument("--out", required=True, help="the profile to write (PROFILE.yaml); with --simulate, a folder")
    p.add_argument(
        "--simulate",
        default=None,
        metavar="REALITY",
        help="write the experiments' logs from comat's simulator at this layer (a level, a profile "
        "PROFILE.yaml or a JSON mapping of fields) into the folder --out, instead of fitting",
    )
    p.add_argument(
        "--truth",
        default=None,
        metavar="PROFILE",
        help="the layer the logs were simulated at (the truth.yaml --simulate writes, or a level): a "
        "truth column beside the fit",
    )
    p.add_argument("--robots", type=int, default=4, help="robots of a simulated run (default: %(default)s)")
    p.add_argument("--seed", type=int, default=0, help="seed of a simulated run (default: %(default)s)")
    add_force(p)
    p.set_defaults(func=_cmd)
    return p
