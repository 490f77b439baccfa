"""The rows ``comat bench learn`` can time beside the defaults — COMAT with one architecture option
changed, the PPO learners with ``ppo.overlap`` — importable without torch, so the command line
offers the same names the benchmark runs."""

from __future__ import annotations

from comat.models.comat_schema import DECISIONS

__all__ = ["COMAT_VARIANTS", "OVERLAP_CHOICES"]

COMAT_VARIANTS = {**{f"comat_{d}": {"decision": d} for d in DECISIONS}, "comat_one_block": {"heat_blocks": 1}}
"""Name -> ``ComatConfig`` options: one row per decision layer mode and one with a single HEAT
block, to time a candidate default next to today's in one run; ``comat_paper`` (the paper form,
``PAPER_FORM``) is the learn benchmark's own."""

OVERLAP_CHOICES = ("off", "on", "both")
"""``--overlap``: time the PPO learners collecting then updating (``off``), with ``ppo.overlap``
(``on``), or both ways in one run (``both``)."""
