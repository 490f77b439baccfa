"""Every kept policy still loads: each ``policy.pt`` git tracks under ``results/`` and each shipped
policy (``comat/data/pretrained``) passes comat's reader (:func:`comat.rl.checkpoint.load_trained`:
format, version, learner, task and its rules' version, keys and types) and its weights fit the
model its stored config builds, strictly. Loading only: the first file of each distinct (learner,
sizes, model config) goes through :func:`comat.rl.policy.policy_modules`, which builds the model;
the others load into that model the same way, so 166 files take seconds, not minutes."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

from comat.rl import POLICY_FORMAT, load_trained
from comat.rl.policy import PRETRAINED_DIR, policy_modules

ROOT = Path(__file__).resolve().parents[1]


def _kept() -> list[str]:
    """The kept policy files: git's list (results/**/policy.pt, comat/data/pretrained/*.pt); outside a
    checkout (an installed copy), the files on disk."""
    try:
        out = subprocess.run(
            ["git", "-C", str(ROOT), "ls-files", "results/**/policy.pt", "comat/data/pretrained/*.pt"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.split()
    except (OSError, subprocess.CalledProcessError):
        out = []
    if out:
        return out
    found = [*ROOT.glob("results/**/policy.pt"), *PRETRAINED_DIR.glob("*.pt")]
    return sorted(p.relative_to(ROOT).as_posix() for p in found)


KEPT = _kept()
_MODELS: dict[tuple, dict] = {}


def test_there_are_kept_policies_to_check():
    assert len(KEPT) >= 100, KEPT[:5]  # 166 on 2026-12-07: a lost list would pass every case below


@pytest.mark.parametrize("name", KEPT)
def test_a_kept_policy_loads(name):
    data = load_trained(ROOT / name)
    assert data["format"] == POLICY_FORMAT, f"{name} is not a policy file"
    model = json.dumps(data["config"]["model"], sort_keys=True, default=str)
    key = (data["algo"], json.dumps(data["dims"], sort_keys=True), model)
    if key not in _MODELS:  # the first of its kind through comat's own loader, which builds the model
        _MODELS[key] = policy_modules(data, ROOT / name)[0]
        return
    modules = _MODELS[key]
    assert sorted(data["weights"]) == sorted(modules), f"{name}: modules {sorted(data['weights'])}"
    for module_name, module in modules.items():
        module.load_state_dict(data["weights"][module_name], strict=True)  # raises on a missing or misshapen weight
