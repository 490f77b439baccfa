"""The rows ``comat bench learn`` can time beside the defaults — COMAT with one architecture option
changed, the PPO learners with ``ppo.overlap`` — importable without torch, so the command line
offers the same names the benchmark runs."""

from __future__ import annotations

from comat.learners import learner_entry, learner_names
from comat.models import DECISIONS

__all__ = ["COMAT_VARIANTS", "OVERLAP_CHOICES", "WIDE_SLOTS", "learn_rows"]

COMAT_VARIANTS = {**{f"comat_{d}": {"decision": d} for d in DECISIONS}, "comat_one_block": {"heat_blocks": 1}}
"""Name -> ``ComatConfig`` options: one row per decision layer mode and one with a single HEAT
block, to time a candidate default next to today's in one run; ``comat_paper`` (the paper form,
``PAPER_FORM``) is the learn benchmark's own."""

WIDE_SLOTS = 20
"""Robot slots of the ``<team-sized learner>_20`` rows (the Robotarium's largest team)."""

OVERLAP_CHOICES = ("off", "on", "both")
"""``--overlap``: time the PPO learners collecting then updating (``off``), with ``ppo.overlap``
(``on``), or both ways in one run (``both``)."""


def learn_rows() -> list[str]:
    """What ``comat bench learn --algos`` times: every registered learner, COMAT in the paper form
    (``comat_paper``) and with each option of :data:`COMAT_VARIANTS`, and each team-sized learner
    with :data:`WIDE_SLOTS` robot slots (``mat_20``)."""
    names = learner_names()
    wide = [f"{n}_{WIDE_SLOTS}" for n in names if learner_entry(n).team_sized]
    return [*names, "comat_paper", *COMAT_VARIANTS, *wide]
