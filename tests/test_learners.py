"""The learner registry (issue 65): one torch-free list that commands, presets, figures, bench and
policy files read; every registered learner keeps the contract (comat.rl.contract); a bad entry,
a broken learner or an unknown name is refused in one line."""

import dataclasses
import subprocess
import sys

import pytest
import torch

from comat.learners import LearnerEntry, learner_entry, learner_names, load_plugins, register_learner
from comat.rl import check_learner, robot_slots
from comat.rl.config import load_preset, preset_names, resolve


def test_the_registry_and_the_command_line_import_no_torch():
    code = (
        "import sys, comat.learners\n"
        "from comat.cli.main import build_parser\n"
        "build_parser()\n"
        "assert 'torch' not in sys.modules, sorted(m for m in sys.modules if m.startswith('torch'))\n"
        "print(','.join(comat.learners.learner_names()))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip().split(",") == list(learner_names())


@pytest.mark.parametrize("name", learner_names())
def test_every_learner_keeps_the_contract(name):
    entry = learner_entry(name)
    checked = check_learner(name, teams=3)
    assert checked["acts_with"] == list(entry.acts_with)
    full, acting = checked["parameters"]
    assert 0 < acting <= full
    # what the rest of comat derives from the entry
    config = resolve(load_preset("quick"), name, "pcp")
    assert (robot_slots(config) is not None) == entry.team_sized == (checked["robot_slots"] is not None)
    assert entry.samples == (entry.family == "ppo")


@pytest.mark.parametrize("preset", preset_names())
def test_every_preset_resolves_for_every_learner_and_names_only_registered_ones(preset):
    settings = load_preset(preset)
    assert set(settings.get("models") or {}) <= set(learner_names())
    for name in learner_names():
        config = resolve(settings, name, "pcp")
        assert isinstance(config.model, learner_entry(name).config_class())
        assert type(config.trainer).__name__ == {"ppo": "PPOConfig", "qmix": "QmixConfig"}[learner_entry(name).family]


def test_the_paper_preset_has_a_block_for_every_learner():
    """A learner is one module plus a preset block: the paper's preset states each one's sizes."""
    assert set(load_preset("paper")["models"]) == set(learner_names())


def _entry(**changes) -> LearnerEntry:
    base = {
        "name": "probe",
        "label": "Probe",
        "colour": "#123456",
        "family": "ppo",
        "config": "comat.models.ippo:IppoConfig",
        "builder": "comat.models.ippo:build",
    }
    return LearnerEntry(**{**base, **changes})


@pytest.mark.parametrize(
    "changes, message",
    [
        ({"name": "Probe"}, r"^LearnerEntry.name must be lower-case letters and digits, .* got 'Probe'$"),
        ({"name": "cash_caps"}, r"got 'cash_caps'$"),
        ({"colour": "red"}, r"^learner 'probe': colour must be '#rrggbb', got 'red'$"),
        ({"family": "dqn"}, r"^learner 'probe': family must be one of \['ppo', 'qmix'\], got 'dqn'$"),
        ({"builder": "comat.models.ippo.build"}, r"^learner 'probe': builder must be 'module:attribute', got"),
        ({"label": ""}, r"^learner 'probe': label must be a non-empty str, got ''$"),
    ],
)
def test_a_bad_entry_is_refused_in_one_line(changes, message):
    with pytest.raises(ValueError, match=message):
        _entry(**changes)


def test_a_taken_name_or_colour_an_unknown_name_and_a_bad_plug_in_are_named():
    with pytest.raises(ValueError, match="^learner 'comat' is registered already$"):
        register_learner(_entry(name="comat"))
    with pytest.raises(ValueError, match=r"^learner 'probe': colour #D62728 is learner 'comat''s; every"):
        register_learner(_entry(colour="#D62728"))
    with pytest.raises(ValueError, match=r"^algo must be one of \[.*'comat'.*\], got 'ppo'$"):
        learner_entry("ppo")
    with pytest.raises(ValueError, match="^COMAT_LEARNERS entry 'no_such_module:X': module 'no_such_module' did not"):
        load_plugins("no_such_module:X")
    with pytest.raises(ValueError, match="expected module:ENTRY"):
        load_plugins("just_a_module")
    with pytest.raises(ValueError, match=r"comat.models.ippo:Ippo is a type, expected a comat.learners.LearnerEntry"):
        load_plugins("comat.models.ippo:Ippo")
    with pytest.raises(ValueError, match=r"learner 'probe': builder: module 'comat.models.ippo' has no 'nope'"):
        _entry(builder="comat.models.ippo:nope").build(None, None)
    assert "probe" not in learner_names()


class _Peeking(torch.nn.Module):
    """IPPO whose actors also read the mean observation of every slot, padded ones included: the
    defect the contract's padded-slot rule exists for."""

    def __init__(self, inner) -> None:
        super().__init__()
        self.inner, self.layout = inner, inner.layout

    def act(self, obs, mask, state=None, deterministic=False, generator=None):
        return self.inner.act(obs + obs.mean(1, keepdim=True), mask, state, deterministic, generator)

    def evaluate_actions(self, obs, mask, actions, state=None):
        return self.inner.evaluate_actions(obs + obs.mean(1, keepdim=True), mask, actions, state)


def peeking_build(dims, config, acting_only=False):
    from comat.models.ippo import build

    return {key: _Peeking(module) for key, module in build(dims, config, acting_only).items()}


class _Unfaithful(_Peeking):
    """IPPO whose evaluate_actions scores with other weights than act samples with."""

    def evaluate_actions(self, obs, mask, actions, state=None):
        logp, entropy, values = self.inner.evaluate_actions(obs, mask, actions, state)
        return logp - 0.1 * mask, entropy, values

    def act(self, obs, mask, state=None, deterministic=False, generator=None):
        return self.inner.act(obs, mask, state, deterministic, generator)


def unfaithful_build(dims, config, acting_only=False):
    from comat.models.ippo import build

    return {key: _Unfaithful(module) for key, module in build(dims, config, acting_only).items()}


@pytest.mark.parametrize(
    "builder, message",
    [
        ("test_learners:peeking_build", "a padded robot slot changed the real robots' actions"),
        ("test_learners:unfaithful_build", "evaluate_actions scores the sampled actions 0.1 away"),
    ],
)
def test_the_contract_refuses_a_broken_learner(builder, message, monkeypatch):
    from comat import learners

    entry = _entry(builder=builder)
    monkeypatch.setitem(learners._LEARNERS, entry.name, entry)
    with pytest.raises(ValueError, match=f"^learner 'probe': {message}"):
        check_learner("probe", teams=3)


def test_a_config_without_defaults_is_refused(monkeypatch):
    from comat import learners

    @dataclasses.dataclass(frozen=True)
    class NoDefaults:
        hidden: int

    monkeypatch.setattr(sys.modules[__name__], "NoDefaults", NoDefaults, raising=False)
    entry = _entry(config="test_learners:NoDefaults")
    monkeypatch.setitem(learners._LEARNERS, entry.name, entry)
    with pytest.raises(ValueError, match="must have a default for every field"):
        check_learner("probe")
