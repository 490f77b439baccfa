"""What an episode measured: running episodes, the paper's metrics, and the statistics over seeds.

The floor below :mod:`comat.rl`, :mod:`comat.eval` and :mod:`comat.viz`: training logs its
evaluation episodes with the same code and names that ``comat eval`` reports.

* :mod:`comat.measure.episodes`: :func:`run_episodes` plays a policy on a vector env, one row per episode;
* :mod:`comat.measure.metrics`: the reported metrics, their names and confidence intervals;
* :mod:`comat.measure.stats`: t-intervals, Welch tests and the hierarchical bootstrap over seeds.
"""

from __future__ import annotations

from comat.measure.episodes import run_episodes, summarize

__all__ = ["run_episodes", "summarize"]
