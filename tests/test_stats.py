"""comat.measure.stats: intervals over seeds, the hierarchical bootstrap, Welch's test, and the
calibration of each on synthetic scores with a known, dominant seed effect."""

import math

import numpy as np
import pytest
from scipy import stats as sst

from comat.measure.stats import cell_means, hierarchical_bootstrap, holm, iqm, per_seed_means, t_interval, welch

# Synthetic design of the calibration: y[s, c, e] = MU + a_s + b_c + e_sce (the report's case:
# C coalitions, K episodes each, the seed effect dominant).
MU, SD_SEED, SD_COAL, SD_EP, C, K = 50.0, 10.0, 5.0, 8.0, 20, 5


def _scores(rng, seeds, coalition_effects):
    """(S, C, K) synthetic scores on the given coalition effects (C,)."""
    a = rng.normal(0.0, SD_SEED, seeds)
    return MU + a[:, None, None] + coalition_effects[None, :, None] + rng.normal(0.0, SD_EP, (seeds, C, K))


def _stratified_bootstrap(tables, reps, rng):
    """The method ``aggregates.csv`` used through issue 18 (rliable's StratifiedBootstrap with
    coalitions as tasks), vectorized over replicates: (R, S, C) tables -> (R, 2) percentile 95 %
    intervals of the mean, each resample drawing seeds independently within each coalition."""
    n_r, n_s, n_c = tables.shape
    out = np.empty((n_r, 2))
    for r in range(n_r):
        idx = rng.integers(0, n_s, size=(reps, n_s, n_c))
        means = tables[r][idx, np.arange(n_c)].mean(axis=(1, 2))
        out[r] = np.percentile(means, [2.5, 97.5])
    return out


# -- by hand ---------------------------------------------------------------------------------------
def test_episodes_are_averaged_within_coalition_then_seed():
    """K episodes of a coalition are one cell, never K samples: a seed with 3 episodes of coalition
    0 and 1 of coalition 1 scores (mean(cell 0) + cell 1) / 2, not the mean of its 4 episodes."""
    seed = [0, 0, 0, 0, 1, 1]
    coalition = [0, 0, 0, 1, 0, 1]
    value = [1.0, 2.0, 3.0, 10.0, 4.0, 6.0]
    table, seeds, coals = cell_means(seed, coalition, value)
    assert seeds == [0, 1] and coals == [0, 1]
    np.testing.assert_allclose(table, [[2.0, 10.0], [4.0, 6.0]])
    labels, means = per_seed_means(seed, coalition, value)
    assert labels == [0, 1]
    np.testing.assert_allclose(means, [6.0, 5.0])  # not 4.0 (the pooled mean of seed 0's episodes)
    # a t-interval over these is over 2 seeds (df 1), whatever the number of episodes
    ti = t_interval(means)
    assert ti["n"] == 2 and ti["df"] == 1.0
    assert ti["half"] == pytest.approx(sst.t.ppf(0.975, 1) * np.std([6.0, 5.0], ddof=1) / math.sqrt(2))
    assert ti["lo"] == pytest.approx(5.5 - ti["half"]) and ti["hi"] == pytest.approx(5.5 + ti["half"])
    assert math.isnan(t_interval([3.0])["half"])
    # a seed that never played a coalition: the table cannot be built, and says which cell is empty
    with pytest.raises(ValueError, match="seed 1 has no episode of coalition 1"):
        cell_means([0, 0, 1], [0, 1, 0], [1.0, 2.0, 3.0])
    # ... but each seed's mean over the cells it has is still defined
    assert per_seed_means([0, 0, 1], [0, 1, 0], [1.0, 2.0, 3.0])[1].tolist() == [1.5, 3.0]
    with pytest.raises(ValueError, match=r"coalition must have 3 entries \(one per episode\), got 2"):
        cell_means([0, 0, 1], [0, 1], [1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="value must be a non-empty 1-D sequence"):
        per_seed_means([], [], [])


def test_welch_matches_scipy_and_the_satterthwaite_df():
    a, b = np.array([97.5, 89.1, 75.3]), np.array([99.4, 96.8, 99.5, 98.0])
    w = welch(a, b)
    ref = sst.ttest_ind(a, b, equal_var=False)
    assert w["t"] == pytest.approx(ref.statistic) and w["p"] == pytest.approx(ref.pvalue)
    va, vb = a.var(ddof=1) / 3, b.var(ddof=1) / 4
    df = (va + vb) ** 2 / (va**2 / 2 + vb**2 / 3)
    assert w["df"] == pytest.approx(df)
    half = sst.t.ppf(0.975, df) * math.sqrt(va + vb)
    assert w["diff"] == pytest.approx(a.mean() - b.mean())
    assert (w["lo"], w["hi"]) == pytest.approx((w["diff"] - half, w["diff"] + half))
    assert w["lo"] < 0 < w["hi"] and w["p"] > 0.05  # the interval contains 0 exactly when p > 0.05
    assert (w["n_a"], w["n_b"]) == (3, 4)
    # one seed, or no spread on either side: the test is undefined, not 0 or 1
    assert math.isnan(welch([1.0], [2.0, 3.0])["p"])
    one = welch([1.0, 1.0], [1.0, 1.0])
    assert one["diff"] == 0.0 and math.isnan(one["p"]) and math.isnan(one["lo"])
    # spread at rounding level is no spread (a seed at 100 % reached by another float path)
    rounded = welch([100.0, 100.0 - 1.4e-14], [99.8, 99.8 + 2.8e-14])
    assert math.isnan(rounded["p"]) and rounded["diff"] == pytest.approx(0.2)
    assert welch([100.0, 99.9], [99.8, 99.8])["p"] < 1  # a real spread of 0.1 point still counts
    # one side constant is fine (the other carries the spread)
    assert welch([1.0, 1.0, 1.0], [0.0, 0.5, 1.0])["df"] == pytest.approx(2.0)


def test_hierarchical_bootstrap_by_hand():
    rng = np.random.default_rng(0)
    table = rng.normal(size=(4, 12))
    out = hierarchical_bootstrap(table, reps=500, seed=3)
    assert out["mean"] == pytest.approx(table.mean()) and (out["seeds"], out["coalitions"]) == (4, 12)
    assert out["iqm"] == pytest.approx(sst.trim_mean(table.ravel(), 0.25)) == iqm(table)
    assert out["mean_lo"] < out["mean"] < out["mean_hi"] and out["iqm_lo"] < out["iqm"] < out["iqm_hi"]
    assert hierarchical_bootstrap(table, reps=500, seed=3) == out  # a fixed generator: same intervals
    assert hierarchical_bootstrap(table, reps=500, seed=4) != out
    # seeds are resampled as wholes: a table whose seeds differ by a constant and whose coalitions
    # do not vary gives the interval of the mean of the seed values, the bootstrap of 4 numbers
    flat = np.repeat(np.array([[0.0], [1.0], [2.0], [3.0]]), 12, axis=1)
    wide = hierarchical_bootstrap(flat, reps=2000, seed=0)
    assert wide["mean_lo"] == pytest.approx(0.5, abs=0.3) and wide["mean_hi"] == pytest.approx(2.5, abs=0.3)
    one = hierarchical_bootstrap(table[:1])
    assert math.isnan(one["mean_lo"]) and math.isnan(one["iqm_hi"]) and one["mean"] == pytest.approx(table[0].mean())
    with pytest.raises(ValueError, match=r"\(seeds, coalitions\) array, got shape \(3,\)"):
        hierarchical_bootstrap(np.ones(3))
    with pytest.raises(ValueError, match="reps must be an integer >= 1, got 0"):
        hierarchical_bootstrap(table, reps=0)
    with pytest.raises(ValueError, match="finite"):
        hierarchical_bootstrap(np.array([[1.0, np.nan], [2.0, 3.0]]))


def test_stratified_bootstrap_helper_is_rlibles_method():
    """The calibration's vectorized stand-in for the old method draws what rliable draws: its
    interval agrees with rliable's own on the same table (within Monte-Carlo error)."""
    from rliable import library as rly
    from rliable import metrics

    rng = np.random.default_rng(1)
    table = _scores(rng, 3, rng.normal(0.0, SD_COAL, C)).mean(axis=2)
    saved = np.random.get_state()
    try:
        np.random.seed(0)
        _, ci = rly.get_interval_estimates({"x": table}, lambda x: np.array([metrics.aggregate_mean(x)]), reps=4000)
    finally:
        np.random.set_state(saved)
    mine = _stratified_bootstrap(table[None], 4000, rng)[0]
    half = (ci["x"][1, 0] - ci["x"][0, 0]) / 2
    assert mine == pytest.approx(ci["x"][:, 0], abs=0.1 * half)


# -- calibration -----------------------------------------------------------------------------------
def test_calibration_t_over_seeds_covers_and_the_stratified_bootstrap_does_not():
    """1,000 replicates of a 3-seed evaluation on one fixed set of 20 coalitions (5 episodes each).
    Estimand: the mean over the seed distribution on these coalitions, MU + mean(b). The 95 %
    t-interval over per-seed means covers it in 93–97 % of replicates; rliable's stratified
    bootstrap (seeds resampled within each coalition) in far fewer."""
    rng = np.random.default_rng(2024)
    b = rng.normal(0.0, SD_COAL, C)
    truth = MU + b.mean()
    for seeds in (3, 12):
        scores = np.stack([_scores(rng, seeds, b) for _ in range(1000)])  # (R, S, C, K)
        seed_col = np.repeat(np.arange(seeds), C * K)
        coal_col = np.tile(np.repeat(np.arange(C), K), seeds)
        covered = 0
        for y in scores:
            ti = t_interval(per_seed_means(seed_col, coal_col, y.ravel())[1])
            covered += ti["lo"] <= truth <= ti["hi"]
        assert 0.93 <= covered / 1000 <= 0.97, (seeds, covered)
    old = _stratified_bootstrap(scores[:, :3].mean(axis=3), 1000, rng)  # the same tables' first 3 seeds
    old_cover = np.mean((old[:, 0] <= truth) & (truth <= old[:, 1]))
    assert old_cover < 0.93 and old_cover < 0.5, old_cover  # measured: 26-33 %


def test_calibration_hierarchical_bootstrap_undercovers_with_few_seeds():
    """The hierarchical bootstrap's estimand is the coalition population's mean, MU: each
    replicate draws new coalitions. A percentile interval over 3 resampled seeds is far too narrow
    (measured 73-76 %), and approaches the nominal level only with a dozen seeds: descriptive only."""
    rng = np.random.default_rng(7)
    cover = {}
    for seeds in (3, 5, 12):
        hits = 0
        for r in range(1000):
            table = _scores(rng, seeds, rng.normal(0.0, SD_COAL, C)).mean(axis=2)
            out = hierarchical_bootstrap(table, reps=500, seed=r)
            hits += out["mean_lo"] <= MU <= out["mean_hi"]
        cover[seeds] = hits / 1000
    assert cover[3] < 0.85 < cover[12] < 0.96, cover
    assert cover[3] < cover[5] < cover[12], cover


def test_holm_by_hand_and_against_statsmodels():
    # sorted 0.005, 0.01, 0.03, 0.04 times 4, 3, 2, 1 = 0.02, 0.03, 0.06, 0.04; running maximum 0.06 for the last
    assert holm([0.01, 0.04, 0.03, 0.005]) == pytest.approx([0.03, 0.06, 0.06, 0.02])
    # an undecidable test stays nan and is not in the family: m = 2 here
    out = holm([0.02, math.nan, 0.6])
    assert out[0] == pytest.approx(0.04) and math.isnan(out[1]) and out[2] == pytest.approx(0.6)
    assert holm([0.4, 0.3]) == pytest.approx([0.6, 0.6]) and holm([0.7, 0.9]).tolist() == [1.0, 1.0]  # monotone, capped
    multitest = pytest.importorskip("statsmodels.stats.multitest")
    p = np.random.default_rng(3).uniform(0, 0.2, 40) ** 2
    assert holm(p) == pytest.approx(multitest.multipletests(p, method="holm")[1])
    with pytest.raises(ValueError, match="p must hold p-values in"):
        holm([0.1, 1.5])
