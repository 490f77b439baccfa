"""`comat report` on hand-made run folders: Table I, the generalization table with Welch's tests,
aggregates over seeds (t-interval, hierarchical bootstrap), the figures, new sets and endpoints,
older files (no coalition index, no new endpoints), and byte-identical reruns."""

import csv
import io
import json
import math

import matplotlib.colors as mcolors
import numpy as np
import pytest
import yaml
from scipy import stats as sst

from comat.cli import main
from comat.eval import SET_NAMES, SETS
from comat.eval.report import PAPER_TABLE1, REPORT_FILES, make_report
from comat.measure.metrics import summarize_ci
from comat.measure.stats import holm


def _episode(ret, steps=80.0, completion=0.5, success=0.0, collisions=0.0, rc=0.0, be=0.0, ae=0.0):
    return {
        "return": ret,
        "steps": steps,
        "progress": completion,
        "finished": success,
        "collisions": collisions,
        "robotarium_collisions": rc,
        "boundary_exits": be,
        "actuator_errors": ae,
        "interventions": 3.0,
        "fallbacks": 0.0,
        "recoveries": 1.0,
    }


SIZES = {"train": (3, 5), "val": (3, 7), "test": (2, 4), "scale": (10, 20), "size": (2, 20), "capability": (3, 5)}
"""Team sizes of the two coalitions each fake set has."""


def _write_run(folder, algo, task, seed, rows, k=1, train_return=10.0):
    folder.mkdir(parents=True)
    config = {"algo": algo, "task": task, "seed": seed, "tier": "unicycle", "total_env_steps": 25600}
    (folder / "config.yaml").write_text(yaml.safe_dump({"config": config}))
    lines = ["env_steps,updates,episode_return"] + [f"{2560 * j},{j},{train_return * j / 10}" for j in range(1, 11)]
    (folder / "progress.csv").write_text("\n".join(lines) + "\n")
    (folder / "evaluation_unicycle.json").write_text(json.dumps({"episodes_per_coalition": k, "rows": rows}))


def _set_row(algo, task, split, ret, success, prog, k=1, keyed=False, extra=None):
    """Two coalitions (returns ret -/+ 1), K episodes each in the order comat eval plays them
    (coalition i % 2); ``keyed``: rows carry "coalition" (issue 28); ``extra(i)``: more keys."""
    eps = []
    for i in range(2 * k):
        c = i % 2
        e = {**_episode(ret + (2 * c - 1), success=success, completion=prog), "team_size": SIZES[split][c]}
        if keyed:
            e.update(coalition=c, episode_in_coalition=i // 2)
        if extra:
            e.update(extra(i))
        eps.append(e)
    return {
        "policy": algo,
        "task": task,
        "set": split,
        "tier": "unicycle",
        "episodes": len(eps),
        "metrics": summarize_ci(eps),
        "per_episode": eps,
    }


def _fake_run(folder, algo, task, seed, train_return, test_return, success, scale_return=None, progress=0.5):
    """A run folder as `comat train` + `comat eval` left it before issue 28: one episode per
    coalition, two coalitions per set (team sizes 3, 5 on U_train; 2, 4 on U_test; 10, 20 on
    U_scale when ``scale_return`` is given), no coalition index, no new endpoints."""
    rows = [
        _set_row(algo, task, "train", train_return, success, progress),
        _set_row(algo, task, "test", test_return, success, progress / 2),
    ]
    if scale_return is not None:
        rows.append(_set_row(algo, task, "scale", scale_return, success, progress / 4))
    _write_run(folder, algo, task, seed, rows, train_return=train_return)


def _csv(path):
    return list(csv.DictReader(io.StringIO(path.read_text())))


def test_retention_names_the_seeds_it_covers(tmp_path):
    """A seed with no U_train progress has no retention: the mean is over the others, and the table
    says so instead of printing the seed count of the row."""
    for seed, progress in enumerate((0.8, 0.4, 0.0)):
        _fake_run(tmp_path / f"r{seed}", "qmix", "pcp", seed, 40.0, 30.0, 0.0, progress=progress)
    out = tmp_path / "results"
    out.mkdir()
    gen = make_report([tmp_path / f"r{seed}" for seed in range(3)], out)["generalization"][0]
    assert gen["seeds"] == 3 and gen["test_retention_seeds"] == 2 and gen["test_retention"] == pytest.approx(0.5)
    row = next(line for line in (out / "generalization.md").read_text().splitlines() if line.startswith("| PCP"))
    assert row.endswith("| 50.0 ± 0.0 (2 of 3 seeds) |"), row


def test_report_on_fake_runs(tmp_path, capsys):
    _fake_run(tmp_path / "a", "comat", "pcp", 0, 40.0, 30.0, 1.0, progress=0.8)
    _fake_run(tmp_path / "b", "comat", "pcp", 1, 60.0, 50.0, 0.5, progress=0.4)
    out = tmp_path / "results"
    out.mkdir()
    result = make_report([tmp_path / "a", tmp_path / "b"], out)
    assert result["groups"] == {"comat/pcp": 2} and result["sets"] == ["train", "test"]
    assert sorted(result["files"]) == sorted(REPORT_FILES)
    for name in REPORT_FILES:
        assert (out / name).stat().st_size > 0
        magic = {"png": b"\x89PNG\r\n\x1a\n", "pdf": b"%PDF"}.get(name.rsplit(".", 1)[1])
        if magic:
            assert (out / name).read_bytes()[: len(magic)] == magic
    md = (out / "table1.md").read_text()
    # mean over the two seeds ± t(0.975, 1) · sd/√2 = 12.706 · 14.142 / 1.414
    assert "| PCP | Mean return | 50.00 ± 127.06 | — |" in md
    assert "| PCP | Finished (paper: completion) | 75.0% [0.0, 100.0] | 92.8% |" in md
    assert "| PCP | Env-step budget per run | 25,600 | 4,000,000 |" in md
    # every caption states the interval method
    method = "mean over seeds ± 95 % t-interval over per-seed means"
    assert method in md and "each seed's mean first averages its 1 episode(s) per coalition, then its coalitions" in md
    gen_md = (out / "generalization.md").read_text()
    assert gen_md.count(method) == 2  # the progress and the finished-share tables (no new endpoints here)
    gen = result["generalization"][0]
    assert gen["train_return"] == 50.0 and gen["test_return"] == 40.0 and gen["test_return_ratio"] == pytest.approx(0.8)
    # progress retention: per seed progress on U_test / on U_train (0.4/0.8 and 0.2/0.4), then the mean
    assert gen["train_progress"] == pytest.approx(0.6) and gen["test_retention"] == pytest.approx(0.5)
    assert not any(k.startswith("scale") for k in gen)  # old runs: train and test only
    assert not any("progress_auc" in k or "time_to_90" in k for k in gen)  # older files: no such columns
    assert "progress AUC" not in gen_md and "Steps to 90" not in gen_md
    assert gen["paper_retention_return_ratio"] == 0.88
    assert PAPER_TABLE1[("pcp", "return")]["comat"] == 82.47
    assert "* PCP: COMAT alone, no baseline in these runs: nothing to compare." in gen_md
    with pytest.raises(FileNotFoundError, match="not a run folder"):
        make_report([tmp_path / "results"], out)
    # Runs without `comat eval`: a warning for some, an error (nothing written) for all.
    (tmp_path / "b" / "evaluation_unicycle.json").unlink()
    out2 = tmp_path / "results2"
    out2.mkdir()
    assert make_report([tmp_path / "a", tmp_path / "b"], out2)["runs"] == 2
    assert "b has no evaluation" in capsys.readouterr().err
    (tmp_path / "a" / "evaluation_unicycle.json").unlink()
    with pytest.raises(ValueError, match=r"none of the 2 run folder\(s\) has an evaluation"):
        make_report([tmp_path / "a", tmp_path / "b"], out2)
    assert main(["report", str(tmp_path / "a"), "--out", str(tmp_path / "fresh")]) == 2
    assert "has an evaluation" in capsys.readouterr().err and not (tmp_path / "fresh").exists()  # no folder left


def test_report_with_u_scale_team_size_and_fixed_colours(tmp_path, monkeypatch, capsys):
    from comat.eval import figures

    for seed in range(3):
        _fake_run(
            tmp_path / f"c{seed}",
            "comat",
            "hmt",
            seed,
            10.0 + seed,
            8.0,
            1.0,
            scale_return=5.0 + seed,
            progress=0.6 + 0.1 * seed,
        )
    _fake_run(tmp_path / "m0", "mat", "hmt", 0, 9.0, 7.0, 1.0)  # an old run: no U_scale evaluation
    drawn = {}
    real_save = figures.save

    def keep(fig, stem):
        drawn[stem.name] = fig
        return real_save(fig, stem)

    monkeypatch.setattr(figures, "save", keep)
    colours = []
    for order in (
        [*[tmp_path / f"c{s}" for s in range(3)], tmp_path / "m0"],
        [tmp_path / "m0", *[tmp_path / f"c{s}" for s in range(3)]],
    ):
        out = tmp_path / f"out{len(colours)}"
        assert main(["report", *map(str, order), "--out", str(out)]) == 0
        printed = capsys.readouterr().out
        assert "scale/train retention" in printed
        gen = {r["algo"]: r for r in _csv(out / "generalization.csv")}
        assert float(gen["comat"]["scale_retention"]) == pytest.approx(0.25)  # progress/4 over progress, every seed
        assert gen["mat"]["scale_retention"] == "nan"  # U_scale columns, empty for the run without it
        # bars: each algorithm's colour, whatever the order the runs came in; sets by hatching only
        ax = drawn["fig5_generalization"].axes[0]
        bars = {
            (round(p.get_x() + p.get_width() / 2, 3), p.get_hatch()): p.get_facecolor()[:3]
            for p in ax.patches
            if hasattr(p, "get_hatch") and p.get_width() > 0
        }
        colours.append(sorted({tuple(round(c, 3) for c in v) for v in bars.values()}))
        assert {h for _, h in bars} == {figures.SET_HATCHES[s] for s in ("train", "test", "scale")}
        assert drawn["fig5_generalization"].axes[1].get_ylim()[0] == 0  # progress from 0
        # team size figure: every size evaluated, the training sizes marked, intervals over 3 seeds
        fig6 = drawn["fig6_team_size"]
        lines = {ln.get_label(): ln for ln in fig6.axes[0].get_lines()}
        comat = next(ln for k, ln in lines.items() if k.startswith("COMAT (3 seeds)"))
        assert list(comat.get_xdata()) == [2, 3, 4, 5, 10, 20]
        assert comat.get_color() == figures.algo_colour("comat")
        assert "U_train's sizes 3, 5, 7" in fig6.axes[0].get_xlabel()
        assert fig6.axes[1].get_ylim() == (0.0, 105.0)  # progress from 0
        # the count behind every point: one coalition of each size per seed for both, so once per size
        assert [t.get_text() for t in fig6.axes[1].texts] == ["1"] * 6
        assert "coalitions of that size per seed" in fig6.texts[0].get_text()
        rows = _csv(out / "aggregates.csv")
        assert {(r["algo"], r["set"]) for r in rows} >= {("comat", "scale"), ("mat", "test")}
    assert colours[0] == colours[1]
    expected = sorted(tuple(round(c, 3) for c in mcolors.to_rgb(figures.algo_colour(a))) for a in ("comat", "mat"))
    assert all(any(np.allclose(c, e, atol=0.01) for e in expected) for c in colours[0])


def test_team_size_counts_per_algorithm_where_they_differ(tmp_path, monkeypatch):
    """Where algorithms average different numbers of coalitions (or seeds) at a size, each point
    carries its own count, in its algorithm's colour."""
    from comat.eval import figures

    drawn = {}
    monkeypatch.setattr(figures, "save", lambda fig, stem: drawn.setdefault(stem.name, fig) and [])
    by_size = {
        ("comat", "pcp"): {
            2: [{"return": 1.0, "progress": 0.5, "coalitions": 2}] * 3,
            4: [{"return": 1.0, "progress": 0.5, "coalitions": 1}] * 2,
        },
        ("mat", "pcp"): {2: [{"return": 1.0, "progress": 0.5, "coalitions": 1}] * 3},
    }
    figures.fig_team_size(by_size, ["pcp"], ["mat", "comat"], {"pcp": {"mat": [1], "comat": [1]}}, tmp_path / "f")
    labels = {(t.get_text(), t.get_color()) for t in drawn["f"].axes[1].texts}
    assert labels == {
        ("1", figures.algo_colour("mat")),
        ("2", figures.algo_colour("comat")),
        ("1 (2 seeds)", figures.algo_colour("comat")),
    }


def test_generalization_compares_with_welch_tests(tmp_path):
    """generalization.md/.csv: progress ± t-interval per set, and COMAT − each baseline with Welch's
    test over per-seed means, whose p decides; "not evaluated", "not decidable" with one seed or no
    spread, and a sentence for a task without baselines."""
    runs = []
    finished = {"comat": (1.0, 1.0, 1.0), "mappo": (0.5, 0.5, 0.5), "qmix": (0.0, 0.5, 1.0)}
    progress = {}
    for algo, base, step in (("comat", 0.8, 0.02), ("mappo", 0.2, 0.02), ("qmix", 0.6, 0.3)):
        progress[algo] = [base + step * seed for seed in range(3)]
        for seed in range(3):
            runs.append(tmp_path / f"{algo}{seed}")
            _fake_run(
                runs[-1],
                algo,
                "pcp",
                seed,
                10.0,
                8.0,
                finished[algo][seed],
                scale_return=5.0,
                progress=progress[algo][seed],
            )
    runs.append(tmp_path / "mat0")
    _fake_run(runs[-1], "mat", "pcp", 0, 9.0, 7.0, 1.0)  # one seed, no U_scale
    runs.append(tmp_path / "comat_hmt")
    _fake_run(runs[-1], "comat", "hmt", 0, 9.0, 7.0, 1.0)  # a task no baseline ran
    out = tmp_path / "out"
    out.mkdir()
    make_report(runs, out)
    md = (out / "generalization.md").read_text()
    assert "| PCP | COMAT | 3 | 82.0 ± 5.0 | 41.0 ± 2.5 | 20.5 ± 1.2 | 50.0 ± 0.0 | 25.0 ± 0.0 |" in md
    one = "(1 seed, no interval)"
    assert f"| PCP | MAT | 1 | 50.0 {one} | 25.0 {one} | — | 50.0 {one} | — |" in md
    assert "| PCP | MAPPO | 3 | 50.0 ± 0.0 | 50.0 ± 0.0 | 50.0 ± 0.0 |" in md  # the finished share per set
    assert "| PCP | QMIX | 3 | 50.0 [0.0, 100.0] | 50.0 [0.0, 100.0] | 50.0 [0.0, 100.0] |" in md

    def line(*parts):
        return next(ln for ln in md.splitlines() if ln.startswith("| PCP | " + " | ".join(parts) + " |"))

    # COMAT vs MAPPO on U_scale progress: per seed progress/4, the same spread: Welch's t with df 4
    a, b = np.array(progress["comat"]) / 4, np.array(progress["mappo"]) / 4
    ref = sst.ttest_ind(a, b, equal_var=False)
    half = sst.t.ppf(0.975, 4) * math.sqrt(a.var(ddof=1) / 3 + b.var(ddof=1) / 3)
    mappo = line("U_scale", "progress", "MAPPO")
    assert (
        f"| 20.5 ± 1.2 | 5.5 ± 1.2 | +15.0 [{100 * (0.15 - half):+.1f}, {100 * (0.15 + half):+.1f}] | "
        f"{ref.statistic:.2f} | 4.0 | < 0.001 | < 0.001 | COMAT higher (p < 0.05) |"
    ) in mappo
    qmix = line("U_scale", "progress", "QMIX")
    q = sst.ttest_ind(a, np.array(progress["qmix"]) / 4, equal_var=False)
    assert f"| {q.pvalue:.3f} | " in qmix and qmix.endswith(" | not separated (p ≥ 0.05) |"), qmix
    assert line("U_scale", "progress", "MAT").endswith("| — | — | — | — | not evaluated on U_scale |")
    assert line("U_test", "progress", "MAT").endswith("| not decidable (needs 2+ seeds each) |")
    # finished share: COMAT 1, 1, 1 against MAPPO 0.5, 0.5, 0.5: no spread, no test (not p = 0)
    no_spread = "| not decidable (no spread over seeds on either side) |"
    assert line("U_train", "finished share", "MAPPO").endswith(no_spread)
    t = 0.5 / math.sqrt(np.var(finished["qmix"], ddof=1) / 3)  # COMAT has no spread: df = 2, QMIX's alone
    p = 2 * sst.t.sf(t, 2)
    qmix = line("U_train", "finished share", "QMIX")
    assert f"| {t:.2f} | 2.0 | {p:.3f} | " in qmix and qmix.endswith(" | not separated (p ≥ 0.05) |"), qmix
    assert "* HMT: COMAT alone, no baseline in these runs: nothing to compare." in md
    assert "The test decides" in md and "That verdict's p is not adjusted for multiplicity" in md
    # Holm p: every decidable test's exact p (the csv's) adjusted over the table's family, in the table's order
    gen = {(r["task"], r["algo"]): r for r in _csv(out / "generalization.csv")}
    nouns = {"progress": "progress", "finished share": "finished", "progress AUC": "progress_auc"}
    keys = {name: split for split, name in SET_NAMES.items()} | nouns
    tested = [ln.split(" | ") for ln in md.splitlines() if ln.startswith("| PCP | U_") and ln.count(" | ") == 11]
    exact = [float(gen[("pcp", c[3].lower())][f"{keys[c[1]]}_{keys[c[2]]}_welch_p"]) for c in tested]
    family = [(c, p) for c, p in zip(tested, exact) if not math.isnan(p)]
    assert len(family) == 9 and f"Holm p adjusts it over the {len(family)} tests of this table" in md
    expected = holm([p for _, p in family])
    assert [c[10] for c, _ in family] == ["< 0.001" if h < 0.001 else f"{h:.3f}" for h in expected]
    assert any(c[9] != c[10] for c, _ in family)  # adjusted, not copied
    n_kept, n_sep = sum(h < 0.05 for h in expected), sum(p < 0.05 for _, p in family)
    assert f"{n_kept} of the {n_sep} 'higher / lower' verdicts keep p < 0.05 after it" in md
    # the csv carries the same test on the baseline's row (COMAT − it); COMAT's own row has none
    gen = {(r["task"], r["algo"]): r for r in _csv(out / "generalization.csv")}
    row = gen[("pcp", "mappo")]
    assert float(row["scale_progress_comat_diff"]) == pytest.approx(0.15)
    assert float(row["scale_progress_welch_t"]) == pytest.approx(ref.statistic)
    assert float(row["scale_progress_welch_p"]) == pytest.approx(ref.pvalue)
    assert float(row["scale_progress_welch_df"]) == pytest.approx(4.0)
    assert float(row["scale_progress_comat_diff_lo"]) == pytest.approx(0.15 - half)
    assert gen[("pcp", "comat")]["scale_progress_welch_p"] == "nan"
    # COMAT's runs alone (e.g. its wheels-tier report): the report says there is nothing to compare with
    alone = tmp_path / "alone"
    alone.mkdir()
    make_report([r for r in runs if r.name.startswith("comat")], alone)
    assert "* PCP: COMAT alone, no baseline in these runs" in (alone / "generalization.md").read_text()


def test_k_episodes_never_count_as_k_seeds_and_the_coalition_index_is_used(tmp_path):
    """Two seeds, 5 episodes per coalition: every interval is over 2 seeds (df 1), not 20 episodes;
    rows with "coalition" are grouped by it, older rows (no index) as coalition i % C."""

    def spread(i):  # episodes of a coalition differ, so cell means differ from single episodes
        return {"progress": 0.1 * i}

    for name, keyed in (("new", True), ("old", False)):
        for seed in range(2):
            rows = [_set_row("comat", "pcp", "train", 10.0 + 4 * seed, 1.0, 0.5, k=5, keyed=keyed, extra=spread)]
            _write_run(tmp_path / name / f"s{seed}", "comat", "pcp", seed, rows, k=5)
    outs = {}
    for name in ("new", "old"):
        outs[name] = tmp_path / f"out_{name}"
        outs[name].mkdir()
        make_report([tmp_path / name / f"s{seed}" for seed in range(2)], outs[name])
    agg = {r["metric"]: r for r in _csv(outs["new"] / "aggregates.csv")}
    ret = agg["return"]
    assert (ret["seeds"], ret["coalitions"], ret["episodes_per_coalition"], ret["t_df"]) == ("2", "2", "5", "1")
    per_seed = [10.0, 14.0]  # each seed: coalitions at ret -/+ 1, averaged
    half = sst.t.ppf(0.975, 1) * np.std(per_seed, ddof=1) / math.sqrt(2)
    assert float(ret["mean_over_seeds"]) == 12.0 and float(ret["t_ci95_hi_over_seeds"]) == pytest.approx(12.0 + half)
    # the cells (coalition 0 = episodes 0, 2, 4, 6, 8): progress 0.4 and 0.5 in each seed
    assert float(agg["progress"]["iqm_of_cells"]) == pytest.approx(0.45)
    assert (outs["old"] / "aggregates.csv").read_text() == (outs["new"] / "aggregates.csv").read_text()
    md = (outs["new"] / "table1.md").read_text()
    assert f"| PCP | Mean return | 12.00 ± {half:.2f} |" in md
    assert "each seed's mean first averages its 5 episode(s) per coalition" in md
    # a file whose episodes are not in i % C order: the "coalition" key, not the position, groups them
    rows = [_set_row("comat", "pcp", "train", 10.0, 1.0, 0.5, k=5, keyed=True, extra=spread)]
    rows[0]["per_episode"].sort(key=lambda e: e["coalition"])
    _write_run(tmp_path / "sorted" / "s0", "comat", "pcp", 0, rows, k=5)
    _write_run(
        tmp_path / "sorted" / "s1",
        "comat",
        "pcp",
        1,
        [_set_row("comat", "pcp", "train", 14.0, 1.0, 0.5, k=5, keyed=True, extra=spread)],
        k=5,
    )
    out = tmp_path / "out_sorted"
    out.mkdir()
    make_report([tmp_path / "sorted" / f"s{seed}" for seed in range(2)], out)
    assert (out / "aggregates.csv").read_text() == (outs["new"] / "aggregates.csv").read_text()


def test_new_sets_and_endpoints_in_table_order(tmp_path):
    """Sets appear in SETS order under their report names, only those evaluated; progress_auc and
    time_to_90 get their columns, tables, aggregates and (AUC) Welch tests where rows carry them."""
    from comat.team import COALITION_SETS

    assert SETS == COALITION_SETS and set(SET_NAMES) == set(SETS)
    order = ("capability", "size", "train", "val")  # as a file might hold them; U_test, U_scale not evaluated
    for algo, lift in (("comat", 0.1), ("mat", 0.0)):
        for seed in range(2):

            def extra(i, seed=seed, lift=lift):
                return {"progress_auc": 0.5 + lift + 0.01 * seed, "time_to_90": 40.0 - 10 * lift - seed}

            rows = [_set_row(algo, "hmt", s, 10.0, 1.0, 0.5, keyed=True, extra=extra) for s in order]
            _write_run(tmp_path / f"{algo}{seed}", algo, "hmt", seed, rows)
    out = tmp_path / "out"
    out.mkdir()
    result = make_report([tmp_path / f"{a}{s}" for a in ("comat", "mat") for s in range(2)], out)
    assert result["sets"] == ["train", "val", "size", "capability"]
    md = (out / "generalization.md").read_text()
    assert (
        "| Task | Algorithm | Seeds | U_train progress (%) | U_val progress (%) | U_size progress (%) | "
        "U_cap progress (%) | U_val retention (%) | U_size retention (%) | U_cap retention (%) |"
    ) in md
    assert "| HMT | COMAT | 2 | 60.5 ± 6.4 | 60.5 ± 6.4 | 60.5 ± 6.4 | 60.5 ± 6.4 |" in md  # progress AUC
    assert "| HMT | MAT | 2 | 39.5 ± 6.4 | 39.5 ± 6.4 | 39.5 ± 6.4 | 39.5 ± 6.4 |" in md  # steps to 90 %
    assert "| HMT | U_cap | progress AUC | MAT |" in md
    gen = {r["algo"]: r for r in _csv(out / "generalization.csv")}["comat"]
    assert float(gen["size_progress_auc"]) == pytest.approx(0.605) and gen["size_time_to_90_seeds"] == "2"
    assert {r["metric"] for r in _csv(out / "aggregates.csv")} == {
        "return",
        "progress",
        "finished",
        "progress_auc",
        "time_to_90",
    }
    assert not any(f"{name} progress (%)" in md or f"| {name} |" in md for name in ("U_test", "U_scale"))


def test_reference_rows_are_over_coalitions(tmp_path):
    """Reference policies (one policy each): mean ± t-interval over the set's coalitions, each
    coalition's K episodes averaged first."""
    for seed in range(2):
        rows = [_set_row("comat", "pcp", "train", 10.0, 1.0, 0.5, k=3, keyed=True)]
        ref = _set_row("heuristic", "pcp", "train", 20.0, 1.0, 1.0, k=3, keyed=True, extra=lambda i: {"return": i})
        _write_run(tmp_path / f"s{seed}", "comat", "pcp", seed, rows + [ref], k=3)
    out = tmp_path / "out"
    out.mkdir()
    make_report([tmp_path / "s0", tmp_path / "s1"], out)
    md = (out / "table1.md").read_text()
    cells = [np.mean([0, 2, 4]), np.mean([1, 3, 5])]  # coalition 0 = episodes 0, 2, 4
    half = sst.t.ppf(0.975, 1) * np.std(cells, ddof=1) / math.sqrt(2)
    assert f"| PCP | U_train | heuristic | 2.50 ± {half:.2f} | 1.00 ± 0.00 | 100.0% ± 0.0 |" in md
    assert "t-interval over the set's coalitions, each coalition's episodes averaged first" in md


def test_a_report_written_twice_is_the_same_bytes(tmp_path):
    """Every file of a report, the PDFs included (no creation date) and the bootstrap (a fixed
    generator), so regenerating committed results shows a diff only where something changed."""
    for seed in range(3):
        rows = [
            _set_row(
                "comat",
                "pcp",
                s,
                10.0 + seed,
                1.0,
                0.5 + 0.1 * seed,
                k=2,
                keyed=True,
                extra=lambda i: {"progress_auc": 0.1 * i, "time_to_90": 10.0 * i},
            )
            for s in ("train", "scale")
        ]
        _write_run(tmp_path / f"c{seed}", "comat", "pcp", seed, rows, k=2)
    written = []
    for k in range(2):
        out = tmp_path / f"out{k}"
        out.mkdir()
        make_report([tmp_path / f"c{seed}" for seed in range(3)], out)
        written.append({f.name: f.read_bytes() for f in sorted(out.iterdir())})
    assert any(name.endswith(".pdf") for name in written[0])
    boot = _csv(tmp_path / "out0" / "aggregates.csv")[0]
    lo, mean, hi = (float(boot[k]) for k in ("hier_boot_mean_ci95_lo", "mean_over_seeds", "hier_boot_mean_ci95_hi"))
    assert lo < mean < hi
    assert written[0] == written[1]


def test_share_error_bars_stay_inside_0_100():
    from comat.eval.figures import clipped_err

    err = clipped_err([95.0, 50.0, 3.0, np.nan], [10.0, 10.0, 10.0, np.nan])
    np.testing.assert_allclose(err[:, :3], [[10.0, 10.0, 3.0], [5.0, 10.0, 10.0]])
    assert np.isnan(err[:, 3]).all()
