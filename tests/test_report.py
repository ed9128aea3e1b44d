"""Aggregates (IQM, bootstrap CIs, steps to threshold, grouping) against hand-computed values on
synthetic run directories, and the report command's figures and Markdown."""

import csv
import json
import math
import re
import subprocess
import sys
from dataclasses import astuple
from pathlib import Path

import imageio.v2 as imageio
import numpy as np
import pytest

pytest.importorskip("rliable", reason="the report needs the plots extra: pip install -e '.[plots]'")

from conftest import read_only  # noqa: E402
from rliable import metrics as rliable_metrics  # noqa: E402

from lava_bridge_mj.eval import aggregate, cli, findings, report  # noqa: E402
from lava_bridge_mj.eval.config import METHODS, RunConfig  # noqa: E402
from lava_bridge_mj.eval.run_files import METRIC_FIELDS  # noqa: E402

BASE_CONFIG = RunConfig().to_dict()

# four seeds of success from p0 at steps 1000..4000, chosen so that the IQM (mean of the middle two of
# four) is easy by hand: step 1000 -> (0 + 0) / 2, 2000 -> (0.2 + 0.4) / 2, 3000 -> (0.6 + 0.8) / 2,
# 4000 -> (0.9 + 1.0) / 2. First step >= 0.8: 3000, 4000, 2000, never.
P0 = {0: [0.0, 0.2, 0.8, 1.0], 1: [0.0, 0.4, 0.6, 0.9], 2: [0.1, 0.9, 1.0, 1.0], 3: [0.0, 0.0, 0.0, 0.0]}
P0_IQM = [0.0, 0.3, 0.7, 0.95]


def write_run(directory, method="auxss", seed=0, demos=500, p0=(0.0, 0.5), ood=None, train=None, steps=None,
              weights=False, **overrides):
    """A run directory as the runner writes it: config.json, metrics.csv, optionally start_weights.npz."""
    directory.mkdir(parents=True)
    config = {**BASE_CONFIG, "method": method, "seed": seed, "demos": demos, **overrides}
    (directory / "config.json").write_text(json.dumps(config))
    steps = steps or [1000 * (i + 1) for i in range(len(p0))]
    ood = ood if ood is not None else [v / 2 for v in p0]
    train = train if train is not None else [v - 0.5 for v in p0]
    with open(directory / "metrics.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=METRIC_FIELDS)
        writer.writeheader()
        for step, a, b, r in zip(steps, p0, ood, train):
            writer.writerow({name: 0.0 for name in METRIC_FIELDS} |
                            {"step": step, "success_p0": a, "success_ood": b, "train_return": r})
    if weights:
        rng = np.random.default_rng(seed)
        states = np.column_stack([rng.uniform(-5, 5, 30), rng.uniform(-0.1, 0.1, 30), rng.normal(0, 1, (30, 2))])
        probabilities = rng.dirichlet(np.ones(30), size=len(steps))
        np.savez(directory / "start_weights.npz", steps=np.array(steps), states=states, probabilities=probabilities)


def hand_group(tmp_path, seeds=P0, name="hand"):
    for seed, p0 in seeds.items():
        write_run(tmp_path / name / f"seed{seed}", seed=seed, p0=p0)
    [group] = aggregate.group_runs(aggregate.find_runs(tmp_path / name))
    return group


# --- aggregates ------------------------------------------------------------------------------------
def test_iqm_curve_by_hand_and_ci_contains_it(tmp_path):
    group = hand_group(tmp_path)
    assert group.label == "auxss (0.5K)" and group.seeds == [0, 1, 2, 3]
    curve = aggregate.iqm_curves(group, ("success_p0",), reps=1000)["success_p0"]
    np.testing.assert_array_equal(curve.steps, [1000, 2000, 3000, 4000])
    np.testing.assert_allclose(curve.iqm, P0_IQM)
    # the estimator is rliable's aggregate_iqm, step by step
    scores = group.scores("success_p0")
    np.testing.assert_allclose(curve.iqm, [rliable_metrics.aggregate_iqm(scores[:, [t]]) for t in range(4)])
    assert np.all(curve.low <= curve.iqm) and np.all(curve.iqm <= curve.high)
    assert np.all(curve.low >= scores.min(0)) and np.all(curve.high <= scores.max(0))
    assert curve.low[0] == 0.0  # three of four seeds at 0
    assert curve.high[2] - curve.low[2] > 0.2  # 0, 0.6, 0.8, 1.0: a wide interval from four seeds


def test_late_means_average_each_seed_over_the_last_third_then_take_the_iqm(tmp_path):
    group = hand_group(tmp_path)
    late = aggregate.late_means(group, ("success_p0", "success_ood"), reps=1000)
    # steps past 2/3 x 4000: 3000 and 4000; per-seed means 0.9, 0.75, 1.0, 0.0; IQM = (0.75 + 0.9) / 2
    np.testing.assert_array_equal(late["success_p0"].steps, [3000, 4000])
    assert late["success_p0"].iqm == pytest.approx(0.825)
    assert late["success_ood"].iqm == pytest.approx(0.4125)  # write_run's ood is half of p0
    assert late["success_p0"].low <= 0.825 <= late["success_p0"].high
    # two seeds whose window means are 0 and 1: the interval by hand is [0, 1] around 0.5
    two = hand_group(tmp_path, {0: [1.0, 0.0, 0.0, 0.0], 1: [0.0, 1.0, 1.0, 1.0]}, "two")
    assert astuple(aggregate.late_means(two, ("success_p0",), reps=2000)["success_p0"])[1:] == (0.5, 0.0, 1.0)
    # with one evaluation the window is that evaluation
    one = aggregate.late_means(hand_group(tmp_path, {0: [0.4], 1: [0.6]}, "one"), ("success_p0",), reps=100)
    assert one["success_p0"].steps.tolist() == [1000] and one["success_p0"].iqm == pytest.approx(0.5)


def test_ci_narrows_with_more_seeds_and_vanishes_without_spread(tmp_path):
    four = aggregate.iqm_curves(hand_group(tmp_path), ("success_p0",), reps=1000)["success_p0"]
    sixteen_seeds = {4 * copy + seed: p0 for copy in range(4) for seed, p0 in P0.items()}  # same distribution
    sixteen = aggregate.iqm_curves(hand_group(tmp_path, sixteen_seeds, "x16"), ("success_p0",), reps=1000)["success_p0"]
    np.testing.assert_allclose(sixteen.iqm, four.iqm)
    assert (sixteen.high - sixteen.low)[2] < 0.7 * (four.high - four.low)[2]
    same = aggregate.iqm_curves(hand_group(tmp_path, {s: [0.25, 0.75] for s in range(4)}, "flat"), ("success_p0",),
                                reps=200)["success_p0"]
    np.testing.assert_array_equal(same.low, [0.25, 0.75])
    np.testing.assert_array_equal(same.high, [0.25, 0.75])


def test_two_seed_percentile_interval_by_hand(tmp_path):
    # seeds at 0 and 1: resamples {0,0}, {0,1}, {1,1} have IQM (here the plain mean) 0, 0.5, 1 with
    # probabilities 1/4, 1/2, 1/4, so the 2.5% and 97.5% percentiles are 0 and 1
    group = hand_group(tmp_path, {0: [0.0], 1: [1.0]}, "two")
    curve = aggregate.iqm_curves(group, ("success_p0",), reps=2000)["success_p0"]
    assert (curve.iqm[0], curve.low[0], curve.high[0]) == (0.5, 0.0, 1.0)


def test_bootstrap_is_reproducible_and_leaves_numpys_global_generator_alone(tmp_path):
    group = hand_group(tmp_path)
    np.random.seed(7)
    expected_next = np.random.random()
    np.random.seed(7)
    first = aggregate.iqm_curves(group, reps=300)
    assert np.random.random() == expected_next
    np.random.seed(99)  # a different global state must not change the intervals
    second = aggregate.iqm_curves(group, reps=300)
    for metric in aggregate.METRICS:
        np.testing.assert_array_equal(first[metric].low, second[metric].low)
        np.testing.assert_array_equal(first[metric].high, second[metric].high)
    # the seed matters (on continuous values, where percentiles of different resamples differ)
    rng = np.random.default_rng(0)
    spread = hand_group(tmp_path, {s: list(rng.random(3)) for s in range(8)}, "spread")
    one, other = (aggregate.iqm_curves(spread, ("success_p0",), reps=300, seed=s)["success_p0"] for s in (0, 1))
    assert not np.array_equal(one.low, other.low)


def test_steps_to_threshold_per_seed_and_never_reached_counted(tmp_path):
    t = aggregate.steps_to_threshold(hand_group(tmp_path))
    assert t.per_seed == {0: 3000, 1: 4000, 2: 2000, 3: math.inf}
    assert t.reached == 3
    assert t.median == 3500  # of 2000, 3000, 4000, never
    assert t.iqm == 3500  # the middle two of four


@pytest.mark.parametrize("firsts, median, iqm", [
    ([1000, 2000, 2000, 4000, None], 2000, (2000 + 2000 + 4000) / 3),  # five seeds: one trimmed each side
    ([1000, 3000, None, None], math.inf, math.inf),  # half never reached: no honest finite summary
    ([None, None, None], math.inf, math.inf),
])
def test_steps_to_threshold_median_and_iqm(tmp_path, firsts, median, iqm):
    seeds = {}
    for seed, first in enumerate(firsts):
        seeds[seed] = [1.0 if first is not None and step >= first else 0.5 for step in (1000, 2000, 3000, 4000)]
    t = aggregate.steps_to_threshold(hand_group(tmp_path, seeds))
    assert t.reached == sum(f is not None for f in firsts)
    assert t.median == median
    assert t.iqm == pytest.approx(iqm)


def test_groups_by_config_not_by_directory_names_at_any_depth(tmp_path):
    write_run(tmp_path / "a" / "deep" / "auxss-d500" / "seed0", method="hysac", seed=0)  # the name lies
    write_run(tmp_path / "b" / "seed1", method="hysac", seed=1)
    write_run(tmp_path / "c" / "seed0", method="auxss", seed=0, demos=7500)
    write_run(tmp_path / "d" / "seed0", method="auxss", seed=0, strategy={"sigma": 0.2})
    write_run(tmp_path / "d" / "seed1", method="auxss", seed=1, strategy={"sigma": 0.2})
    write_run(tmp_path / "e" / "seed0", method="auxss", seed=0)
    (tmp_path / "f").mkdir()
    (tmp_path / "f" / "config.json").write_text("{}")  # no metrics.csv: not a run
    groups = aggregate.group_runs(aggregate.find_runs(tmp_path))
    labels = {g.label: g.seeds for g in groups}
    assert labels == {"hysac (0.5K)": [0, 1], "auxss (7.5K)": [0],
                      "auxss (0.5K) [strategy.sigma=0.2]": [0, 1], "auxss (0.5K)": [0]}
    # in the runner's method order (auxss before hysac), then demo set
    assert [g.method for g in groups] == sorted((g.method for g in groups), key=METHODS.index)


def test_labels_name_only_what_differs_from_the_defaults(tmp_path):
    # the LayerNorm variant beside HySAC as configured by default: both configs spell the entry out
    sac = RunConfig().to_dict()["sac"]
    write_run(tmp_path / "a" / "seed0", method="hysac", sac={**sac, "critic_layer_norm": False})
    write_run(tmp_path / "b" / "seed0", method="hysac", sac={**sac, "critic_layer_norm": True})
    # a free-form strategy entry set on one group and left out by the other
    write_run(tmp_path / "c" / "seed0", method="auxss", strategy={"ema": 0.5, "kernel_dims": "full"})
    write_run(tmp_path / "d" / "seed0", method="auxss")
    groups = aggregate.group_runs(aggregate.find_runs(tmp_path))
    assert {g.label: g.settings for g in groups} == {
        "hysac (0.5K)": {"sac.critic_layer_norm": "false"},
        "hysac (0.5K) [sac.critic_layer_norm=true]": {"sac.critic_layer_norm": "true"},
        # kernel_dims="full" is not RunConfig's default (a free-form entry has none), so it is named
        'auxss (0.5K) [strategy.ema=0.5, strategy.kernel_dims="full"]':
            {"strategy.ema": "0.5", "strategy.kernel_dims": '"full"'},
        "auxss (0.5K)": {"strategy.ema": "default", "strategy.kernel_dims": "default"}}


def test_a_budget_puts_runs_extended_further_on_one_footing_with_the_others(tmp_path):
    # seeds 0-1 were extended to 4,000 steps, seed 2 stopped at 2,000; `steps` does not split the group
    write_run(tmp_path / "s0", seed=0, p0=[0.0, 0.2, 0.9, 1.0], steps=[1000, 2000, 3000, 4000])
    write_run(tmp_path / "s1", seed=1, p0=[0.0, 0.8, 1.0, 1.0], steps=[1000, 2000, 3000, 4000])
    write_run(tmp_path / "s2", seed=2, p0=[0.1, 0.3], steps=[1000, 2000])
    for path, steps in (("s0", 4000), ("s1", 4000), ("s2", 2000)):
        config = json.loads((tmp_path / path / "config.json").read_text())
        (tmp_path / path / "config.json").write_text(json.dumps({**config, "steps": steps}))
    [every] = aggregate.group_runs(aggregate.find_runs(tmp_path))
    assert every.seeds == [0, 1, 2] and every.label == "auxss (0.5K)"
    assert aggregate.steps_to_threshold(every).per_seed == {0: 3000, 1: 2000, 2: math.inf}

    [budget] = aggregate.group_runs(aggregate.find_runs(tmp_path, budget=2000))
    assert aggregate.steps_to_threshold(budget).per_seed == {0: math.inf, 1: 2000, 2: math.inf}
    assert [run.rows[-1]["step"] for run in budget.runs] == [2000, 2000, 2000]
    [extended] = aggregate.group_runs(aggregate.find_runs(tmp_path, seeds={0, 1}))
    np.testing.assert_array_equal(extended.steps, [1000, 2000, 3000, 4000])
    with pytest.raises(ValueError, match="with evaluations at or before step 500 of seeds \\[2\\]"):
        aggregate.find_runs(tmp_path, budget=500, seeds={2})


def test_curves_use_the_steps_every_seed_has_and_skip_missing_values(tmp_path):
    write_run(tmp_path / "s0", seed=0, p0=[0.0, 0.5, 1.0], train=[0.1, float("nan"), 0.3])
    write_run(tmp_path / "s1", seed=1, p0=[0.2, 0.6], train=[0.2, 0.4])  # still running: one evaluation fewer
    [group] = aggregate.group_runs(aggregate.find_runs(tmp_path))
    curves = aggregate.iqm_curves(group, reps=200)
    np.testing.assert_array_equal(curves["success_p0"].steps, [1000, 2000])
    np.testing.assert_allclose(curves["success_p0"].iqm, [0.1, 0.55])
    assert curves["train_return"].iqm[0] == pytest.approx(0.15)
    assert np.isnan(curves["train_return"].iqm[1]) and np.isnan(curves["train_return"].low[1])


def test_find_runs_refuses_an_empty_tree_and_names_a_broken_config(tmp_path):
    with pytest.raises(ValueError, match="holds no run directory"):
        aggregate.find_runs(tmp_path)
    write_run(tmp_path / "run", seed=0)
    (tmp_path / "run" / "config.json").write_text("{not json")
    with pytest.raises(ValueError, match=re.escape(str(tmp_path / "run" / "config.json"))):
        aggregate.find_runs(tmp_path)


# --- the report command ----------------------------------------------------------------------------
def full_sweep(root, seeds=(0, 1, 2)):
    """Every method at 0.5K and the demo-using ones at 7.5K too, laid out as a sweep writes them."""
    for m, method in enumerate(METHODS):
        for demos in (500, 7500) if method not in ("sac", "omega_ss", "uniform_ss", "goaldist_ss") else (500,):
            for seed in seeds:
                p0 = list(np.clip(np.linspace(0, 1, 5) * (0.4 + 0.06 * m) + 0.1 * seed, 0, 1))
                write_run(root / f"{method}-d{demos}" / f"seed{seed}", method=method, seed=seed, demos=demos, p0=p0,
                          train=None if method not in ("bc", "iql") else [float("nan")] * 5,
                          weights=method == "auxss")


FIGURES = ("benchmark", "demo_size", "start_distributions", "maze")


def test_report_writes_every_figure_and_the_markdown(tmp_path, capsys):
    sweep = tmp_path / "sweep"
    full_sweep(sweep)
    assert report.main([str(sweep), "--reps", "200"]) == 0
    out = sweep / "report"
    assert f"wrote {out / 'report.md'}" in capsys.readouterr().out
    for name in FIGURES:
        assert (out / f"{name}.pdf").stat().st_size > 5_000
        image = imageio.imread(out / f"{name}.png")
        assert image.shape[0] > 300 and image.shape[1] > 900
        assert image[..., :3].std() > 10, f"{name}.png is blank"
    text = (out / "report.md").read_text()
    links = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", text)
    assert sorted(links) == sorted(f"{name}.png" for name in FIGURES)
    assert all((out / link).is_file() for link in links)  # relative to report.md
    assert "Skipped" not in text and "Not in this directory" not in text
    for method in METHODS:
        assert f"| {method} (0.5K) | 3 |" in text  # the last-evaluation table
    assert "| hysac (7.5K) | 3 |" in text
    # auxss is method index 1: p0 ramps to 0.46 + 0.1 * seed, so its IQM at the last step is the middle
    # seed's (three seeds: 25% of 3 trims nothing, the IQM is the mean): (0.46 + 0.56 + 0.66) / 3 = 0.56
    assert re.search(r"\| auxss \(0\.5K\) \| 3 \| 5,000 \| 0\.56 \[", text)
    assert "| sac (0.5K) | 0 of 3 | not reached | not reached |" in text
    assert "start weights" in text and "seed 0" in text
    # over the last third (steps 4,000 and 5,000) auxss's seeds average 0.4025 + 0.1 * seed: IQM 0.5025
    assert "| auxss (0.5K) | 3 | 2 (4,000-5,000) | 0.50 [" in text


def test_report_figures_are_byte_identical_when_regenerated(tmp_path):
    # no timestamps: the committed docs/report* figures change only when their data does
    for seed in (0, 1):
        write_run(tmp_path / "runs" / f"seed{seed}", seed=seed, p0=[0.0, 0.5, 0.9], weights=True)
    outputs = []
    for out in ("a", "b"):
        assert report.main([str(tmp_path / "runs"), "--reps", "50", "--out", str(tmp_path / out)]) == 0
        outputs.append({p.name: p.read_bytes() for p in (tmp_path / out).iterdir()})
    assert any(name.endswith(".pdf") for name in outputs[0])
    assert outputs[0] == outputs[1]


def test_report_budget_and_seeds_select_evaluations_and_runs(tmp_path, capsys):
    sweep = tmp_path / "sweep"
    for seed in (0, 1, 2):
        write_run(sweep / f"seed{seed}", seed=seed, p0=[0.0, 0.5, 0.9, 1.0], weights=True)
    assert report.main([str(sweep), "--budget", "2000", "--seeds", "1,0", "--reps", "50",
                        "--out", str(tmp_path / "out")]) == 0
    text = (tmp_path / "out" / "report.md").read_text()
    assert text.startswith(f"# LavaBridge-v0 report: `{sweep}`, evaluations up to step 2,000 and seeds 0-1")
    assert "| auxss (0.5K) | 2: 0, 1 | 2 (2,000) |" in text
    assert "| auxss (0.5K) | 0 of 2 | not reached |" in text  # 0.9 comes at step 3,000, past the budget
    with pytest.raises(SystemExit):
        report.main([str(sweep), "--budget", "0"])
    assert "expected a positive integer, got 0" in capsys.readouterr().err


def test_report_of_several_directories_and_a_run_given_twice(tmp_path, capsys):
    write_run(tmp_path / "protocol" / "auxss" / "seed0", seed=0, p0=[0.0, 1.0])
    write_run(tmp_path / "ablations" / "seed0", seed=0, p0=[0.0, 0.5], strategy={"ema": 0.5})
    out = tmp_path / "out"
    assert report.main([str(tmp_path / "protocol"), str(tmp_path / "ablations"), "--out", str(out),
                        "--reps", "50"]) == 0
    text = (out / "report.md").read_text()
    assert text.startswith(f"# LavaBridge-v0 report: `{tmp_path / 'protocol'}`, `{tmp_path / 'ablations'}`")
    assert "| auxss (0.5K) [strategy.ema=0.5] | 1: 0 |" in text and "| auxss (0.5K) | 1: 0 |" in text
    # the same run reached twice would count its seed twice: refused, naming both paths
    assert report.main([str(tmp_path / "protocol"), str(tmp_path / "protocol" / "auxss"), "--out",
                        str(tmp_path / "twice")]) == 2
    err = capsys.readouterr().err
    assert "seed 0 of one configuration (auxss, 500 demos on LavaBridge-v0) is in two run directories" in err
    assert not (tmp_path / "twice").exists()


def test_report_skips_figures_whose_methods_are_absent(tmp_path):
    for seed in (0, 1):
        write_run(tmp_path / "sac" / f"seed{seed}", method="sac", seed=seed, p0=[0.0, 0.0, 0.1])
        write_run(tmp_path / "bc" / f"seed{seed}", method="bc", seed=seed, p0=[0.9, 1.0, 1.0])
    out = tmp_path / "figures"
    assert report.main([str(tmp_path), "--out", str(out), "--reps", "100"]) == 0
    text = (out / "report.md").read_text()
    assert "*Skipped: no method has runs with both 0.5K and 7.5K demo transitions.*" in text
    assert "*Skipped: none of auxss, omega_ss, uniform_ss, goaldist_ss has runs here.*" in text
    assert "Not in this directory: auxss, omega_ss" in text  # in the benchmark figure's note
    assert "No AuxSS run with start_weights.npz" in text
    assert (out / "benchmark.png").is_file() and (out / "maze.png").is_file()
    assert not (out / "demo_size.png").exists() and not (out / "start_distributions.png").exists()


@pytest.mark.parametrize("case", ["missing", "empty", "broken"])
def test_report_refuses_bad_input_with_one_line_and_exit_2(tmp_path, capsys, case):
    target = tmp_path / "sweep"
    if case != "missing":
        target.mkdir()
    if case == "broken":
        write_run(target / "seed0")
        (target / "seed0" / "metrics.csv").write_text("step,success_p0\n1000,not-a-number\n")
    assert report.main([str(target)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("lava-bridge-bench report: error:")
    assert str(target) in err
    assert not (target / "report").exists()


def test_cli_dispatches_report_and_its_help_names_the_subcommands(tmp_path, capsys):
    write_run(tmp_path / "run", method="sac")
    assert cli.main(["report", str(tmp_path), "--reps", "50"]) == 0
    assert (tmp_path / "report" / "report.md").is_file()
    with pytest.raises(SystemExit):
        cli.main(["--help"])
    help_text = " ".join(capsys.readouterr().out.split())  # unwrapped
    for name in ("report", "video"):
        assert re.search(r"lava-bridge-bench \{[a-z,]*\b%s\b[a-z,]*\}" % name, help_text), help_text
    result = subprocess.run([sys.executable, "-m", "lava_bridge_mj.eval.report", "--help"],
                            capture_output=True, text=True)
    assert result.returncode == 0 and "--out" in result.stdout


# --- the paper's findings (eval/findings.py) --------------------------------------------------------
def findings_for(tmp_path, runs):
    """runs: {(method, demos, extra config entries as (name, JSON text) pairs): {seed: (p0, ood)}} ->
    the findings by number and the groups."""
    for (method, demos, extra), seeds in runs.items():
        for seed, (p0, ood) in seeds.items():
            write_run(tmp_path / f"{method}-{demos}-{len(extra)}" / f"seed{seed}", method=method, seed=seed,
                      demos=demos, p0=p0, ood=ood, **{k: json.loads(v) for k, v in extra})
    groups = aggregate.group_runs(aggregate.find_runs(tmp_path))
    return {f.number: f for f in findings.check_findings(groups)}, groups


def same(p0, ood=None, seeds=3):
    return {seed: (p0, ood if ood is not None else p0) for seed in range(seeds)}


def test_findings_verdicts_against_hand_computed_criteria(tmp_path):
    # steps are 1000..6000; medians to 0.8: auxss 2000, omega 2000, hysac 6000, jsrl never, uniform 5000,
    # goaldist 2000 (as fast as AuxSS: not "clearly slower")
    ramp = lambda first: [1.0 if step >= first else 0.0 for step in range(1000, 7000, 1000)]  # noqa: E731
    found, _ = findings_for(tmp_path, {
        ("sac", 500, ()): same([0.0, 0.0, 0.1, 0.05, 0.0, 0.0]),
        ("auxss", 500, ()): same(ramp(2000), [0.0, 0.0, 0.0, 0.5, 0.6, 0.7]),
        ("auxss", 500, (("strategy", '{"ema": 0.5}'),)): same(ramp(1000)),  # a variant never stands in for auxss
        ("omega_ss", 500, ()): same(ramp(2000), [0.0, 0.3, 0.3, 0.3, 0.3, 0.3]),
        ("hysac", 500, ()): same(ramp(6000), [0.0] * 5 + [0.4]),
        ("jsrl", 7500, ()): same([0.0] * 6),
        ("hysac_auxss", 500, ()): same(ramp(1000), [0.0] * 5 + [0.69]),
        ("uniform_ss", 500, ()): same(ramp(5000)),
        ("goaldist_ss", 500, ()): same(ramp(2000)),
        ("iql", 500, ()): same([1.0] * 6, [0.5] * 6),
        ("bc", 500, ()): same([0.9] * 6, [0.1] * 6),
    })
    assert found[1].verdict == "reproduced" and "at most 0.10 over 6 evaluations" in found[1].measured
    # 2000 <= 6000 / 3; jsrl (0.5K) and hysac (7.5K) were not run, which the note says
    assert found[2].verdict == "reproduced" and "ratio 0.33" in found[2].measured
    assert "not run: hysac (7.5K), jsrl (0.5K)" in found[2].measured
    assert found[3].verdict == "partly"  # 0.69 beats hysac's 0.4, not auxss's 0.7
    # early (first 3 of 6 evaluations): both 0.0, 1.0, 1.0 from p0; later ood 0.3 < 0.7
    assert found[4].verdict == "reproduced" and "Omega-SS 0.30, AuxSS 0.70" in found[4].measured
    assert found[5].verdict == "partly"  # uniform 5000 > 2000; goaldist 2000 is not later
    assert found[6].verdict == "partly"  # IQL 1.0 / 0.5 holds; BC at 0.9 from p0 does not fail


def test_findings_say_which_runs_are_missing_and_when_a_claim_fails(tmp_path):
    found, groups = findings_for(tmp_path, {
        ("sac", 500, ()): same([0.0, 0.5, 0.9]),
        ("auxss", 500, ()): same([0.0, 0.0, 0.0]),
        ("jsrl", 500, ()): same([0.0, 0.9, 1.0]),
    })
    assert found[1].verdict == "not reproduced"  # SAC reaches 0.9
    assert found[2].verdict == "not reproduced"  # AuxSS never reaches 0.8
    assert found[3].verdict == "missing runs" and found[3].measured == "no runs of hysac_auxss (0.5K), hysac (0.5K)"
    assert {f.verdict for n, f in found.items() if n >= 4} == {"missing runs"}
    assert findings.demo_size_rows(groups) == [] and findings.variant_rows(groups) == []


def test_omega_that_learns_later_than_auxss_does_not_match_it_early(tmp_path):
    # first half (3 of 6 evaluations): Omega-SS's mean IQM p0 is 0.0, AuxSS's (0 + 0.5 + 1) / 3 = 0.5
    found, _ = findings_for(tmp_path, {
        ("auxss", 500, ()): same([0.0, 0.5, 1.0, 1.0, 1.0, 1.0], [0.8] * 6),
        ("omega_ss", 500, ()): same([0.0, 0.0, 0.0, 1.0, 1.0, 1.0], [0.5] * 6),
    })
    assert found[4].verdict == "partly"  # behind from ood (0.5 < 0.8), but not matching early
    assert "first 3 evaluations (to step 3,000): Omega-SS 0.00, AuxSS 0.50" in found[4].measured


def test_findings_compare_online_methods_up_to_the_step_all_of_them_have(tmp_path):
    # Omega-SS has run 3 of 6 evaluations: AuxSS's later ood (0.9) must not be set against its 0.5
    found, groups = findings_for(tmp_path, {
        ("auxss", 500, ()): same([0.0, 1.0, 1.0, 1.0, 1.0, 1.0], [0.5, 0.5, 0.5, 0.9, 0.9, 0.9]),
        ("omega_ss", 500, ()): same([0.0, 1.0, 1.0], [0.5, 0.5, 0.5]),
    })
    assert findings.common_step(groups) == 3000
    assert found[4].verdict == "partly"  # at step 3,000 Omega-SS's ood equals AuxSS's: not behind
    assert "IQM success from ood at the last: Omega-SS 0.50, AuxSS 0.50" in found[4].measured


# --- damaged inputs and outputs that cannot be written ---------------------------------------------
def two_auxss_runs(root):
    """Two AuxSS seeds that both reach 0.8 (seed 0 first) with start weights, and a report of them."""
    for seed in (0, 1):
        write_run(root / f"seed{seed}", seed=seed, p0=[0.0, 0.9, 1.0], weights=True)


@pytest.mark.parametrize("damage", ["truncated", "not a zip", "shapes"])
def test_a_damaged_start_weights_file_is_skipped_with_one_warning(tmp_path, capsys, damage):
    """The maze figure takes the next run's start weights; the damaged file is named on stderr and in
    report.md; the run's curves still count (its metrics are intact)."""
    two_auxss_runs(tmp_path / "runs")
    weights = tmp_path / "runs" / "seed0" / "start_weights.npz"
    if damage == "truncated":
        weights.write_bytes(weights.read_bytes()[:200])
    elif damage == "not a zip":
        weights.write_bytes(b"\x80\x04garbage")
    else:
        np.savez(weights, steps=np.array([1000]), states=np.zeros((5, 4)), probabilities=np.ones((2, 5)))
    assert report.main([str(tmp_path / "runs"), "--reps", "50", "--out", str(tmp_path / "out")]) == 0
    out, err = capsys.readouterr()
    assert len(err.strip().splitlines()) == 1 and err.startswith("lava-bridge-bench report: warning: ")
    assert str(weights) in err and "move it aside or restore it" in err
    text = (tmp_path / "out" / "report.md").read_text()
    assert f"*Skipped: {weights}" in text and f"evaluations of `{tmp_path / 'runs' / 'seed1'}` (seed 1)" in text
    assert "| auxss (0.5K) | 2: 0, 1 |" in text


def fail_on_write(monkeypatch, name, error):
    """Make the atomic write of file `name` raise `error` after writing half of it, as a full disk does."""
    from lava_bridge_mj.eval import atomic

    real = atomic.atomic_write

    def write(path, writer):
        if Path(path).name == name:
            def half(f):
                f.write(b"partial")
                raise error
            return real(path, half)
        return real(path, writer)

    monkeypatch.setattr(atomic, "atomic_write", write)


@pytest.mark.parametrize("name", ["benchmark.png", "start_distributions.pdf", "report.md"])  # first, middle, last
def test_a_full_disk_leaves_the_previous_report_as_it_was(tmp_path, capsys, monkeypatch, name):
    import errno

    two_auxss_runs(tmp_path / "runs")
    out = tmp_path / "out"
    argv = [str(tmp_path / "runs"), "--reps", "50", "--out", str(out)]
    assert report.main(argv) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    write_run(tmp_path / "runs" / "seed2", seed=2, p0=[0.0, 0.2, 0.3])  # the next report differs
    capsys.readouterr()
    fail_on_write(monkeypatch, name, OSError(errno.ENOSPC, "No space left on device"))
    assert report.main(argv) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert err == (f"lava-bridge-bench report: error: cannot write the report into {out}: No space left on device "
                   f"({out / name}); {out} is left as it was\n")
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before  # nothing new, nothing half-written


def test_a_report_that_cannot_be_written_anywhere_leaves_nothing(tmp_path, capsys, monkeypatch):
    two_auxss_runs(tmp_path / "runs")
    fail_on_write(monkeypatch, "benchmark.png", PermissionError(13, "Permission denied"))
    out = tmp_path / "new" / "report"
    assert report.main([str(tmp_path / "runs"), "--reps", "50", "--out", str(out)]) == 2
    assert "Permission denied" in capsys.readouterr().err
    assert not (tmp_path / "new").exists()  # the directories it made are gone again


@pytest.mark.parametrize("out, message", [
    ("/proc/lava-bridge-report", "/proc/lava-bridge-report"),  # refused even to root
    ("runs/seed0/metrics.csv/report", "is not a directory"),
    ("runs/seed0/metrics.csv", "exists and is not a directory"),
])
def test_an_out_that_cannot_be_a_directory_is_one_line(tmp_path, capsys, monkeypatch, out, message):
    two_auxss_runs(tmp_path / "runs")
    monkeypatch.chdir(tmp_path)
    before = sorted(p.name for p in tmp_path.rglob("*"))
    assert report.main(["runs", "--reps", "50", "--out", out]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and err.startswith("lava-bridge-bench report: error: ")
    assert message in err
    assert sorted(p.name for p in tmp_path.rglob("*")) == before


def test_a_read_only_run_directory_is_one_line(tmp_path, capsys):
    two_auxss_runs(tmp_path / "runs")
    with read_only(tmp_path / "runs"):
        assert report.main([str(tmp_path / "runs"), "--reps", "50"]) == 2
    err = capsys.readouterr().err
    assert err == (f"lava-bridge-bench report: error: --out {tmp_path / 'runs' / 'report'} cannot be made: "
                   f"{tmp_path / 'runs'} is not a writable directory\n")


@pytest.mark.parametrize("change, message", [
    ({"seed": "abc"}, "seed must be an integer, got 'abc'"),
    ({"demos": None}, "demos must be an integer, got None"),
    ({"method": 5}, "method must be a name, got 5"),
    ({"env": {"bridge_length": "long"}}, "its env settings make no maze"),
    ({"env": [1, 2]}, "its env settings make no maze"),
])
def test_a_config_the_report_cannot_use_is_one_line_naming_it(tmp_path, capsys, change, message):
    two_auxss_runs(tmp_path / "runs")
    for seed in (1, 0):  # the maze is drawn from one of them, in the env settings of its run
        config = tmp_path / "runs" / f"seed{seed}" / "config.json"
        config.write_text(json.dumps({**json.loads(config.read_text()), **change}))
    assert report.main([str(tmp_path / "runs"), "--reps", "50", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "config.json" in err and message in err, err
    assert not (tmp_path / "out").exists()


def test_an_interrupted_report_leaves_out_as_it_was(tmp_path, capsys, monkeypatch):
    two_auxss_runs(tmp_path / "runs")
    fail_on_write(monkeypatch, "maze.png", KeyboardInterrupt())
    assert report.main([str(tmp_path / "runs"), "--reps", "50", "--out", str(tmp_path / "out")]) == 130
    assert "interrupted" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("argv, message", [
    (["--seeds", "0-99999999"], "expected at most 1,000 seeds"),  # parse_seeds would take hours
    (["--reps", "100000000"], "--reps must be in 1-100,000, got 100000000"),  # a bootstrap of hours
    (["--reps", "0"], "--reps must be in 1-100,000, got 0"),
])
def test_report_refuses_options_that_would_run_for_hours(tmp_path, capsys, argv, message):
    two_auxss_runs(tmp_path / "runs")
    with pytest.raises(SystemExit) as exit_:
        report.main([str(tmp_path / "runs"), *argv])
    assert exit_.value.code == 2 and message in capsys.readouterr().err
    assert not (tmp_path / "runs" / "report").exists()


def test_runs_of_several_tasks_are_grouped_and_compared_within_their_task(tmp_path, capsys):
    sweep = tmp_path / "sweep"
    for task, shift in (("LavaBridge-v0", 0.0), ("LavaBridgeNarrow-v0", -0.5)):
        sub = sweep if task == "LavaBridge-v0" else sweep / task
        for method in ("auxss", "uniform_ss"):
            for seed in (0, 1):
                p0 = list(np.clip(np.array([0.2, 0.9, 1.0]) + shift, 0, 1))
                write_run(sub / f"{method}-d500" / f"seed{seed}", method=method, seed=seed, p0=p0,
                          weights=method == "auxss", env_id=task)
    groups = aggregate.group_runs(aggregate.find_runs(sweep))
    assert [(g.task, g.method, g.label) for g in groups] == [
        ("LavaBridge-v0", "auxss", "auxss (0.5K)"), ("LavaBridge-v0", "uniform_ss", "uniform_ss (0.5K)"),
        ("LavaBridgeNarrow-v0", "auxss", "auxss (0.5K) on LavaBridgeNarrow-v0"),
        ("LavaBridgeNarrow-v0", "uniform_ss", "uniform_ss (0.5K) on LavaBridgeNarrow-v0")]
    assert all(g.settings == {} for g in groups)  # the task is not a setting of the method
    assert report.main([str(sweep), "--reps", "50"]) == 0
    out = sweep / "report"
    text = (out / "report.md").read_text()
    assert text.startswith("# Report on 2 tasks (LavaBridge-v0, LavaBridgeNarrow-v0)")
    v0, narrow = text.split("\n## LavaBridge-v0\n")[1].split("\n## LavaBridgeNarrow-v0\n")
    # each task's part compares its own groups only: one pair each, never across tasks
    assert "| auxss (0.5K) | uniform_ss (0.5K) |" in v0 and "on LavaBridgeNarrow-v0" not in v0
    assert "| auxss (0.5K) on LavaBridgeNarrow-v0 | uniform_ss (0.5K) on LavaBridgeNarrow-v0 |" in narrow
    assert "| auxss (0.5K) | uniform_ss (0.5K) on" not in text
    # both reach 0.8 on v0 (2 of 2 seeds) and never on Narrow, where success tops out at 0.5
    assert "| auxss (0.5K) | 100,000" not in v0  # (steps are 1,000-3,000)
    assert re.search(r"\| auxss \(0\.5K\) on LavaBridgeNarrow-v0 \| [0-9,]+ \| 0 of 2 \[", narrow)
    assert re.search(r"\| auxss \(0\.5K\) \| [0-9,]+ \| 2 of 2 \[", v0)
    assert "The paper's findings" in v0 and "The paper's findings" not in narrow
    for task in ("LavaBridge-v0", "LavaBridgeNarrow-v0"):
        for name in ("benchmark", "start_distributions", "maze"):
            assert (out / f"{task}_{name}.png").is_file() and f"({task}_{name}.png)" in text


def test_the_maze_figure_of_a_task_draws_its_own_layout(tmp_path):
    import lava_bridge_mj

    write_run(tmp_path / "seed0", env_id="LavaBridgeTwoCrossings-v0")
    [run] = aggregate.find_runs(tmp_path)
    assert report._layout(run) == lava_bridge_mj.task_layout("LavaBridgeTwoCrossings-v0")
    assert report._layout(run) != lava_bridge_mj.task_layout("LavaBridge-v0")
