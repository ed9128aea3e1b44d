"""`lava-bridge-bench report DIR [--out OUT]`: the paper's figures and tables from a sweep directory.

    lava-bridge-bench report runs/sweep                 # writes runs/sweep/report/
    python -m lava_bridge_mj.eval.report runs/sweep --out paper_figures

Runs are found under DIR at any depth by their config.json and metrics.csv and grouped by configuration
(eval/aggregate.py: task, method and demo set, plus any other setting that differs). OUT receives, each
as PNG and PDF (named TASK_NAME, with one part of report.md per task, when DIR holds runs of several tasks):
    benchmark          training return and success from p0 and from ood versus steps, every method
                       (its 0.5K-demo runs where it has them): the paper's benchmark comparison
    demo_size          the same for the methods that have both 0.5K and 7.5K runs (solid and dashed)
    start_distributions  AuxSS, Omega-SS, U-SS and GoalDist-SS: the start-distribution study
    maze               the maze (walls, lava, goal, p0 blobs, ood spots, the candidate demo states) and
                       an AuxSS run's start-state probabilities on those states at a few evaluations
and report.md, which embeds the PNGs (relative links) with its tables: IQM and 95% CI at the last
evaluation per group, the steps to p0 success >= 0.8 with how many seeds got there, the reach counts
with exact intervals and the area under the success curve, and the pairwise tests of `comparison_pairs`
(eval/statistics.py: exact and rank tests, Holm-corrected, with the power of each). Lines are IQMs
across seeds, bands their 95% stratified-bootstrap CIs (rliable). A figure none of whose methods is in
DIR is skipped with a line in report.md saying so. For the offline methods (bc, iql) a step is a
gradient step, not an env step; their legend entries say so.

Everything is drawn into a temporary directory inside OUT and moved into place only once all of it
is written, report.md last: an error (a damaged run file, a full disk) leaves OUT as it was. A
start_weights.npz that cannot be read is skipped with a warning (on stderr and in report.md), the
maze figure taking its start weights from another run: that run's metrics, and so its curves and
tables, are intact, and one damaged side file should not cost the whole report.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import shutil
import signal
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from lava_bridge_mj.eval.atomic import nearest_existing
from lava_bridge_mj.eval.aggregate import (BOOTSTRAP_REPS, BOOTSTRAP_SEED, METRICS, THRESHOLD, Curve, Group,
                                           RunRecord, find_runs, group_runs, iqm_curves, late_means,
                                           steps_to_threshold)
from lava_bridge_mj.eval.arguments import format_seeds, in_main_thread as _in_main_thread, positive_int as _positive_int
from lava_bridge_mj.eval.arguments import raise_keyboard_interrupt as _interrupt
from lava_bridge_mj.eval import statistics as stats
from lava_bridge_mj.eval.findings import check_findings, common_step, demo_size_rows, is_default, pick, variant_rows
from lava_bridge_mj.eval.summary import read_start_weights
from lava_bridge_mj.tasks import DEFAULT_ENV_ID
from lava_bridge_mj.eval.sweep import seed_list

STANDARD_DEMOS = 500
"""The paper's benchmark protocol gives every demo-using method 500 transitions (0.5K)."""
DEMO_SIZES = (500, 7500)
START_STUDY = ("auxss", "omega_ss", "uniform_ss", "goaldist_ss")
"""The start-distribution study's methods (paper, figure 'ss_dists')."""
OFFLINE = ("bc", "iql")
METRIC_TITLES = {"train_return": "training return", "success_p0": "success from p0 (ID)",
                 "success_ood": "success from ood (OOD)"}
MAX_REPS = 100_000
"""Most bootstrap resamples: twice rliable's 50,000, which already took 16.5 s per group and metric."""
WEIGHT_SNAPSHOTS = 4
"""Evaluations of the AuxSS run whose start-state probabilities the maze figure paints."""


# --- figures -------------------------------------------------------------------------------------
def _pyplot():
    import matplotlib

    matplotlib.use("Agg")  # files only, never a window
    import matplotlib.pyplot as plt

    return plt


def _style(groups: list[Group]) -> dict[str, dict]:
    """Colour by method (the same in every figure), line style by demo set, then by variant."""
    from lava_bridge_mj.eval.config import METHODS

    plt = _pyplot()
    palette = plt.get_cmap("tab10").colors
    variant_styles = (":", "-.", (0, (5, 1, 1, 1)))
    styles, seen = {}, {}
    for group in groups:
        index = METHODS.index(group.method) if group.method in METHODS else len(METHODS)
        key = (group.method, group.demos)
        variant = seen.get(key, 0)
        seen[key] = variant + 1
        base = "-" if group.demos == STANDARD_DEMOS else "--"
        styles[group.label] = {"color": palette[index % len(palette)],
                               "linestyle": base if variant == 0 else variant_styles[(variant - 1) % 3]}
    return styles


def _legend_label(group: Group) -> str:
    suffix = ", gradient steps" if group.method in OFFLINE else ""
    return f"{group.label} (n={len(group.runs)}{suffix})"


def curves_figure(groups: list[Group], curves: dict[str, dict[str, Curve]], title: str):
    """Three panels (training return, success from p0, from ood): IQM lines with CI bands per group."""
    plt = _pyplot()
    styles = _style(groups)
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2), constrained_layout=True)
    for ax, metric in zip(axes, ("train_return", "success_p0", "success_ood")):
        for group in groups:
            curve, style = curves[group.label][metric], styles[group.label]
            ax.plot(curve.steps, curve.iqm, label=_legend_label(group), linewidth=1.8, **style)
            ax.fill_between(curve.steps, curve.low, curve.high, color=style["color"], alpha=0.18, linewidth=0)
        ax.set_title(METRIC_TITLES[metric])
        ax.set_xlabel("steps")
        ax.grid(alpha=0.3)
        if metric.startswith("success"):
            ax.set_ylim(-0.03, 1.03)
            ax.set_ylabel("task completion rate (IQM)")
        else:
            ax.set_ylabel("mean episode return (IQM)")
    handles, labels = axes[0].get_legend_handles_labels()
    columns = max(1, min(4, len(labels), 190 // (max(map(len, labels)) + 8)))  # about 190 characters fit a row
    fig.legend(handles, labels, loc="outside lower center", ncol=columns, fontsize=8, frameon=False)
    fig.suptitle(title)
    return fig


def draw_maze(ax, layout) -> None:
    """The maze from above: floor, outer walls, lava pits, goal, p0 blobs (green), ood spots (blue)."""
    from matplotlib.patches import Circle, Rectangle

    def box(b, **style):
        ax.add_patch(Rectangle((b.x - b.half_x, b.y - b.half_y), 2 * b.half_x, 2 * b.half_y, **style))

    hx, hy = layout.half_extent
    ax.add_patch(Rectangle((-hx, -hy), 2 * hx, 2 * hy, facecolor="#f2efe8", edgecolor="none", zorder=0))
    for wall in layout.walls.values():
        box(wall, facecolor="#4d4d4d", edgecolor="none", zorder=1)
    for pit in layout.lava_pits.values():
        box(pit, facecolor="#e8571e", edgecolor="none", zorder=1, label="lava")
    for disc in layout.p0_blobs:
        ax.add_patch(Circle(disc[:2], disc.radius, facecolor="#2ca02c", alpha=0.55, zorder=2, label="p0"))
    for disc in layout.ood_spots:
        ax.add_patch(Circle(disc[:2], disc.radius, facecolor="#1f5fd0", alpha=0.55, zorder=2, label="ood"))
    ax.add_patch(Circle(layout.goal, layout.goal_radius, facecolor="none", edgecolor="#b30000", linewidth=2, zorder=2))
    ax.plot(*layout.goal, marker="x", color="#b30000", markersize=8, zorder=2, label="goal")
    t = layout.wall_thickness
    ax.set_xlim(-hx - t, hx + t)
    ax.set_ylim(-hy - t, hy + t)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])


def maze_figure(layout, states: np.ndarray | None, weights: list[tuple[float, float, np.ndarray]], caption: str):
    """The maze with the candidate states, then one panel per (step, p0 success, probabilities) with the
    probabilities painted on the states, relative to uniform (1 = uniform sampling)."""
    plt = _pyplot()
    from matplotlib.colors import LogNorm

    rows = 1 + math.ceil(len(weights) / 2)
    fig = plt.figure(figsize=(12, 2.7 * rows + 0.6), constrained_layout=True)
    grid = fig.add_gridspec(rows, 2)
    top = fig.add_subplot(grid[0, :])
    draw_maze(top, layout)
    if states is not None:
        top.scatter(states[:, 0], states[:, 1], s=9, color="black", zorder=3, label="demo states")
    handles, labels = top.get_legend_handles_labels()
    unique = dict(zip(labels, handles))
    top.legend(unique.values(), unique.keys(), loc="upper center", bbox_to_anchor=(0.5, -0.02), ncol=5, fontsize=8,
               frameon=False)
    top.set_title(caption, fontsize=10)
    if weights:
        relative = [p * len(p) for _, _, p in weights]
        positive = np.concatenate(relative)
        positive = positive[positive > 0]
        norm = LogNorm(vmin=positive.min(), vmax=max(positive.max(), positive.min() * 1.01))
        for i, ((step, success, _), rel) in enumerate(zip(weights, relative)):
            ax = fig.add_subplot(grid[1 + i // 2, i % 2])
            draw_maze(ax, layout)
            order = np.argsort(rel)  # the most likely starts drawn last, on top
            points = ax.scatter(states[order, 0], states[order, 1], c=np.clip(rel[order], norm.vmin, None), s=14,
                                cmap="viridis", norm=norm, zorder=3, edgecolors="none")
            ax.set_title(f"step {step:,.0f} (p0 success {success:.2f})", fontsize=9)
        fig.colorbar(points, ax=fig.axes[1:], shrink=0.8,
                     label="start probability x number of states (1 = uniform)")
    return fig


def save_figure(fig, out: Path, name: str) -> list[Path]:
    """`name`.png and `name`.pdf in `out`, each written atomically."""
    from lava_bridge_mj.eval.atomic import atomic_write

    paths = []
    # no creation date in the PDF: the same data must give the same bytes, or every `make report`
    # shows every figure as changed
    metadata = {"png": None, "pdf": {"CreationDate": None}}
    for kind in ("png", "pdf"):
        path = out / f"{name}.{kind}"
        atomic_write(path, lambda f: fig.savefig(f, format=kind, dpi=130, metadata=metadata[kind]))
        paths.append(path)
    _pyplot().close(fig)
    return paths


# --- choosing what goes where --------------------------------------------------------------------
def benchmark_groups(groups: list[Group], methods: tuple[str, ...] | None = None) -> list[Group]:
    """Per method (all, or those in `methods`): its 0.5K groups, or all of its groups if it has none."""
    chosen = []
    for method in dict.fromkeys(g.method for g in groups):
        if methods is not None and method not in methods:
            continue
        mine = [g for g in groups if g.method == method]
        standard = [g for g in mine if g.demos == STANDARD_DEMOS]
        chosen += standard or mine
    return chosen


def demo_size_groups(groups: list[Group]) -> list[Group]:
    """The groups of every method that has runs with each demo set of the study (0.5K and 7.5K)."""
    both = [m for m in dict.fromkeys(g.method for g in groups)
            if all(any(g.method == m and g.demos == d for g in groups) for d in DEMO_SIZES)]
    return [g for g in groups if g.method in both and g.demos in DEMO_SIZES]


def comparison_pairs(groups: list[Group]) -> list[tuple[Group, Group]]:
    """The pairs the report tests, each once: every pair of the start-distribution study's groups;
    AuxSS (0.5K) against every other online method's 0.5K group; each method's 0.5K against its 7.5K
    group; and each variant against its method's default configuration on the same demo set."""
    pairs: list[tuple[Group, Group]] = []

    def add(a: Group | None, b: Group | None) -> None:
        if a is not None and b is not None and a is not b and (a, b) not in pairs and (b, a) not in pairs:
            pairs.append((a, b))

    defaults = [g for g in groups if is_default(g)]
    study = [g for g in defaults if g.method in START_STUDY and g.demos == STANDARD_DEMOS]
    for i, a in enumerate(study):
        for b in study[i + 1:]:
            add(a, b)
    for b in defaults:
        if b.demos == STANDARD_DEMOS and b.method not in OFFLINE:
            add(pick(groups, "auxss"), b)
    for g in defaults:
        if g.demos == DEMO_SIZES[0]:
            add(g, pick(groups, g.method, DEMO_SIZES[1]))
    for g in groups:
        if not is_default(g):
            add(pick(groups, g.method, g.demos), g)
    return pairs


def weights_run(groups: list[Group], threshold: float, usable=None) -> RunRecord | None:
    """The AuxSS run whose start weights the maze figure shows: of the first AuxSS group (0.5K first)
    with start_weights.npz, the lowest seed that reached the threshold, else its lowest seed. `usable`
    (a run -> bool) can rule out runs whose file cannot be read."""
    for group in benchmark_groups(groups, ("auxss",)):
        runs = [run for run in group.runs
                if (run.path / "start_weights.npz").is_file() and (usable is None or usable(run))]
        if runs:
            reached = steps_to_threshold(group, threshold).per_seed
            solved = [run for run in runs if math.isfinite(reached[run.seed])]
            return (solved or runs)[0]
    return None


def _layout(run: RunRecord):
    """The maze of the run's env settings; ValueError naming its config.json when they make none."""
    import lava_bridge_mj

    fields = {f.name for f in dataclasses.fields(lava_bridge_mj.Layout)}
    env = run.config.get("env", {})
    try:  # the task's layout with any layout field the run's env settings change
        return dataclasses.replace(lava_bridge_mj.task_layout(run.task), **{k: v for k, v in env.items() if k in fields})
    except (AttributeError, TypeError, ValueError) as error:
        raise ValueError(f"{run.path / 'config.json'}: its env settings make no maze ({error})") from None


# --- the report ----------------------------------------------------------------------------------
def _interval(curve: Curve, digits: int = 2) -> str:
    if not len(curve.steps) or not np.isfinite(curve.iqm[-1]):
        return "-"
    return f"{curve.iqm[-1]:.{digits}f} [{curve.low[-1]:.{digits}f}, {curve.high[-1]:.{digits}f}]"


def _steps(value: float) -> str:
    return f"{value:,.0f}" if math.isfinite(value) else "not reached"


def _runs_table(groups: list[Group]) -> list[str]:
    lines = ["| group | seeds | evaluations used (last step) |", "|---|---|---:|"]
    for g in groups:
        steps = g.steps
        ragged = "" if len(set(g.last_steps)) == 1 else \
            f"; seeds stop at {min(g.last_steps):,.0f}-{max(g.last_steps):,.0f}, later evaluations not shown"
        last = f"{steps[-1]:,.0f}" if len(steps) else "none in common"
        lines.append(f"| {g.label} | {len(g.runs)}: {', '.join(map(str, g.seeds))} | {len(steps)} ({last}{ragged}) |")
    return lines


def _maze_section(groups: list[Group], threshold: float, where: str, out: Path, warnings: list[str],
                  name: str = "maze") -> list[str]:
    """Draw NAME.png/pdf; the report's paragraph about it. A start_weights.npz that cannot be read is
    passed over, with a line in `warnings`."""
    weights: dict[Path, tuple | None] = {}

    def usable(run: RunRecord) -> bool:
        if run.path not in weights:
            try:
                weights[run.path] = read_start_weights(run.path / "start_weights.npz")
            except ValueError as error:
                weights[run.path] = None
                warnings.append(f"{error}. The maze figure does not use it.")
        return weights[run.path] is not None

    chosen = weights_run(groups, threshold, usable)
    source = chosen or next((r for g in groups for r in g.runs
                             if (r.path / "start_weights.npz").is_file() and usable(r)), None)
    states, snapshots = None, []
    if source is not None:  # every run's start_weights.npz holds its candidate states
        steps, states, probabilities = weights[source.path]
    if chosen is not None:  # only the evaluations the report keeps (see --budget)
        kept = steps <= chosen.rows[-1]["step"]
        steps, probabilities = steps[kept], probabilities[kept]
        success = {row["step"]: row["success_p0"] for row in chosen.rows}
        picks = np.unique(np.linspace(0, len(steps) - 1, min(WEIGHT_SNAPSHOTS, len(steps))).round().astype(int))
        snapshots = [(float(steps[i]), success.get(float(steps[i]), math.nan), probabilities[i]) for i in picks]
        caption = (f"start weights of {chosen.method} seed {chosen.seed} ({chosen.path}); "
                   f"{len(states)} candidate demo states")
        text = (f"The maze (walls grey, lava orange, goal red, p0 blobs green, ood spots blue) with the {len(states)} "
                f"candidate demo states, then AuxSS's start-state probabilities on them at {len(snapshots)} "
                f"evaluations of `{chosen.path}` (seed {chosen.seed}).")
    else:
        with_states = f" with the {len(states)} candidate demo states" if states is not None else ""
        caption = "the maze" + with_states
        text = (f"The maze{with_states}. *No AuxSS run with start_weights.npz in {where}: the start weights "
                f"are not shown.*")
    layout = _layout(source or groups[0].runs[0])
    save_figure(maze_figure(layout, states, snapshots, caption), out, name)
    notes = [f"*Skipped: {warning}*" for warning in warnings]
    return [text, *(["", *notes] if notes else []), "", f"![The maze and AuxSS start weights]({name}.png)", "",
            f"[PDF]({name}.pdf)"]


def _last_evaluation_table(groups: list[Group], curves: dict[str, dict[str, Curve]]) -> list[str]:
    lines = ["IQM [95% CI] across seeds at the last step all of a group's seeds have.", "",
             "| group | seeds | step | success from p0 | success from ood | training return |",
             "|---|---:|---:|---:|---:|---:|"]
    for g in groups:
        c = curves[g.label]
        step = f"{c['success_p0'].steps[-1]:,.0f}" if len(c["success_p0"].steps) else "-"
        lines.append(f"| {g.label} | {len(g.runs)} | {step} | {_interval(c['success_p0'])} | "
                     f"{_interval(c['success_ood'])} | {_interval(c['train_return'], 3)} |")
    return lines


def _late_table(groups: list[Group], reps: int) -> list[str]:
    lines = [f"Each seed's mean over its evaluations in the last third of the group's steps (past two thirds of "
             f"the last one), then the IQM [95% CI] across seeds: where a group ended up, without the swing of a "
             f"single evaluation.", "",
             "| group | seeds | evaluations (steps) | success from p0 | success from ood |", "|---|---:|---|---:|---:|"]
    for g in groups:
        late = late_means(g, ("success_p0", "success_ood"), reps=reps)
        window = late["success_p0"].steps
        steps = f"{len(window)} ({window[0]:,.0f}-{window[-1]:,.0f})" if len(window) else "-"
        cells = [f"{m.iqm:.2f} [{m.low:.2f}, {m.high:.2f}]" if math.isfinite(m.iqm) else "-" for m in late.values()]
        lines.append(f"| {g.label} | {len(g.runs)} | {steps} | {' | '.join(cells)} |")
    return lines


def _threshold_table(groups: list[Group], threshold: float) -> list[str]:
    lines = ["Per seed, the first evaluation at or above the threshold. Median and IQM are over all seeds, a seed "
             "that never got there counting as infinitely late: they read *not reached* when such seeds reach the "
             "middle of the distribution.", "",
             "| group | reached | median | IQM | per seed (seed: step) |", "|---|---:|---:|---:|---|"]
    for g in groups:
        t = steps_to_threshold(g, threshold)
        per_seed = ", ".join(f"{seed}: {_steps(step) if math.isfinite(step) else 'never'}"
                             for seed, step in t.per_seed.items())
        lines.append(f"| {g.label} | {t.reached} of {len(t.per_seed)} | {_steps(t.median)} | {_steps(t.iqm)} | "
                     f"{per_seed} |")
    return lines


def _ci(reach: stats.ReachCount) -> str:
    return f"{reach.reached} of {reach.seeds} [{reach.low:.2f}, {reach.high:.2f}]"


def _p(raw: float, adjusted: float) -> str:
    return f"{raw:.3g} ({adjusted:.3g})" if math.isfinite(raw) else "-"


def _reach_table(groups: list[Group], threshold: float) -> list[str]:
    lines = [f"Per group, the seeds whose success from p0 reached {threshold:g} at some evaluation, with the exact "
             f"(Clopper-Pearson) {stats.CONFIDENCE:.0%} interval of the reach rate, and the area under each seed's "
             f"success-from-p0 curve divided by the steps it spans (1 = success 1.0 at every evaluation), averaged "
             f"over seeds.", "",
             "| group | up to step | reached [95% CI of the rate] | area under the success curve |",
             "|---|---:|---:|---:|"]
    for g in groups:
        outcomes = stats.seed_outcomes(g, threshold)
        if outcomes is None:
            lines.append(f"| {g.label} | - | - | - |")
            continue
        lines.append(f"| {g.label} | {outcomes.step:,.0f} | {_ci(outcomes.reach)} | {outcomes.auc.mean():.2f} |")
    return lines


def _pairwise_section(groups: list[Group], threshold: float) -> list[str]:
    """The pairwise table: every test of eval/statistics.py for each of `comparison_pairs`."""
    compared, skipped = [], []
    for a, b in comparison_pairs(groups):
        until = min(a.steps[-1], b.steps[-1]) if len(a.steps) and len(b.steps) else None
        outcomes = [stats.seed_outcomes(g, threshold, until) for g in (a, b)] if until is not None else [None]
        if None in outcomes:
            skipped.append(f"{a.label} against {b.label}")
            continue
        compared.append((a, b, stats.compare(*outcomes)))
    lines = [f"Each pair up to the last step both groups have. Two-sided p-values, raw and (in brackets) "
             f"Holm-adjusted across the {len(compared)} pairs of this table, one family per column: Fisher's exact "
             f"test on the reach counts; Mann-Whitney U on the steps to {threshold:g}, a seed that never got there "
             f"tied last; permutation tests of the difference in mean final and late-window success from p0 "
             f"(the last third of the steps). Rank and permutation p-values use every split of the seeds when there "
             f"are at most {stats.PERMUTATIONS:,}, else {stats.PERMUTATIONS:,} random ones (seed "
             f"{stats.PERMUTATION_SEED}). P(A > B) is rliable's probability of improvement on late-window success. "
             f"Power is that of Fisher's test at {stats.ALPHA:g} with these seeds if the observed reach rates were "
             f"the true ones; seeds needed is the fewest seeds per group that give {stats.POWER:.0%} power there "
             f"(exact, by enumerating the binomial outcomes; '> {stats.MAX_SEEDS}' beyond); both read '-' when the "
             f"observed rates are equal. The verdict names each test that rejects at {stats.ALPHA:g} after the "
             f"correction, and is *not enough seeds to decide* when none does: the groups are then not ranked. A "
             f"group of one seed gets no rank or permutation test ('-')."]
    if not compared:
        return lines + ["", "*No pairs to compare here.*"]
    needed = stats.seeds_needed(0.5, 0.8)
    lines[0] += (f" For reference, a reach rate of 0.8 against 0.5 needs {needed} seeds per group "
                 f"for {stats.POWER:.0%} power." if needed else "")
    lines += ["", "| A | B | up to step | reached A, B | reach p | steps p | final p | late p | P(A > B) | power | "
                  "seeds needed | verdict |", "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|"]
    for (a, b, c), adjusted in zip(compared, stats.holm_by_test([c for _, _, c in compared])):
        equal = c.a.reach.rate == c.b.reach.rate  # no difference to detect
        power = "-" if equal else f"{c.power:.2f}"
        needed = "-" if equal else str(c.seeds_needed) if c.seeds_needed is not None else f"> {stats.MAX_SEEDS}"
        cells = [a.label, b.label, f"{c.a.step:,.0f}", f"{c.a.reach.reached}/{c.a.reach.seeds}, "
                 f"{c.b.reach.reached}/{c.b.reach.seeds}", *(_p(c.p[t], adjusted[t]) for t in stats.TESTS),
                 f"{c.improvement:.2f}", power, needed, stats.decision(c, adjusted, a.label, b.label)]
        lines.append("| " + " | ".join(cells) + " |")
    if skipped:
        lines += ["", f"*Not compared (no evaluation step in common): {'; '.join(skipped)}.*"]
    return lines


def _findings_section(groups: list[Group], heading: str = "##") -> list[str]:
    step = common_step(groups)
    cut = f" Online methods are compared up to step {step:,.0f}, the last that all of them have." if step else ""
    lines = ["Each claim checked against the fixed criterion written in eval/findings.py (default "
             f"configurations only; variants are the ablation table's).{cut}", "",
             "| # | claim | measured | verdict |", "|---:|---|---|---|"]
    lines += [f"| {f.number} | {f.claim} | {f.measured} | **{f.verdict}** |" for f in check_findings(groups)]
    for title, rows in (("Demo-size study (finding 7): 0.5K vs 7.5K", demo_size_rows(groups)),
                        ("AuxSS ablations (finding 8)", variant_rows(groups))):
        lines.extend(["", f"{heading}# {title}", ""])
        lines.extend(rows or ["*No runs for this table here.*"])
    return lines


def build_report(roots: Path | Sequence[Path], out: Path, threshold: float = THRESHOLD, reps: int = BOOTSTRAP_REPS,
                 runs: list[RunRecord] | None = None, budget: int | None = None,
                 seeds: list[int] | None = None) -> Path:
    """Write every figure and report.md for the runs under `roots` (one directory or several; or
    `runs`, found there already) into `out`; returns report.md's path. `budget` and `seeds` select
    evaluations and runs as `find_runs` does. ValueError when a root holds no such run or a run's
    files cannot be used, OSError when `out` cannot be written: either way `out` is left as it was
    (everything is written into a temporary directory there first). Warnings (start weights that
    cannot be read) go to stderr and into report.md."""
    roots = [Path(roots)] if isinstance(roots, (str, Path)) else [Path(root) for root in roots]
    if runs is None:
        runs = [run for root in roots for run in find_runs(root, budget, seeds)]
    groups = group_runs(runs)
    curves = {g.label: iqm_curves(g, METRICS, reps=reps) for g in groups}
    made = [d for d in (out, *out.parents) if not d.exists()]
    out.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=".report-", dir=out))
    try:
        warnings = _write_report(staging, roots, groups, curves, threshold, reps, budget, seeds)
        for warning in warnings:
            print(f"lava-bridge-bench report: warning: {warning}", file=sys.stderr)
        _publish(staging, out)
    except BaseException as error:
        if isinstance(error, OSError) and error.filename and Path(error.filename).parent == staging:
            error.filename = str(out / Path(error.filename).name)  # the file the user asked for
        shutil.rmtree(staging, ignore_errors=True)
        for directory in made:  # innermost first; only those this call made, and only while empty
            try:
                directory.rmdir()
            except OSError:
                break
        raise
    shutil.rmtree(staging, ignore_errors=True)
    return out / "report.md"


def _publish(staging: Path, out: Path) -> None:
    """Move every file written in `staging` into `out`, report.md last (renames within one filesystem:
    no space needed, nothing half-written), then make the renames durable."""
    from lava_bridge_mj.eval.atomic import fsync_directory

    for path in sorted(staging.iterdir(), key=lambda p: (p.name == "report.md", p.name)):
        os.replace(path, out / path.name)
    fsync_directory(out)


def _write_report(out: Path, roots: list[Path], groups: list[Group], curves: dict, threshold: float, reps: int,
                  budget: int | None, seeds: list[int] | None) -> list[str]:
    """Every figure and report.md into `out`; returns the warnings. Runs of one task make the report's
    sections; runs of several tasks make one part per task (figures named TASK_NAME), since methods are
    compared within a task only."""
    from lava_bridge_mj.eval.atomic import atomic_write_text

    warnings: list[str] = []
    where = ", ".join(f"`{root}`" for root in roots)
    selection = [f"evaluations up to step {budget:,}" if budget is not None else "",
                 f"seeds {format_seeds(sorted(seeds))}" if seeds is not None else ""]
    selection = " and ".join(part for part in selection if part)
    tasks = list(dict.fromkeys(g.task for g in groups))
    title = f"{tasks[0]} report" if len(tasks) == 1 else f"Report on {len(tasks)} tasks ({', '.join(tasks)})"
    lines = [f"# {title}: {where}" + (f", {selection}" if selection else ""), "",
             f"{sum(len(g.runs) for g in groups)} runs in {len(groups)} groups (one configuration each; "
             f"eval/aggregate.py says how runs are grouped). Lines and table entries are interquartile means "
             f"(IQM) across seeds; bands and brackets are 95% stratified-bootstrap confidence intervals (rliable, "
             f"{reps:,} resamples, bootstrap seed {BOOTSTRAP_SEED}). Curves use the evaluation steps that every "
             f"seed of a group has. For bc and iql a step is a gradient step on the demos.", "",
             *_runs_table(groups)]
    for task in tasks:
        mine = [g for g in groups if g.task == task]
        if len(tasks) == 1:
            lines.extend(_task_sections(mine, curves, threshold, reps, where, out, warnings, "##", ""))
        else:
            lines.extend(["", f"## {task}", "", f"{sum(len(g.runs) for g in mine)} runs in {len(mine)} groups."])
            lines.extend(_task_sections(mine, curves, threshold, reps, where, out, warnings, "###", f"{task}_"))
    atomic_write_text(out / "report.md", "\n".join(lines) + "\n")
    return warnings


def _task_sections(groups: list[Group], curves: dict, threshold: float, reps: int, where: str, out: Path,
                   warnings: list[str], heading: str, prefix: str) -> list[str]:
    """The figures and tables of the groups of one task, under `heading`-level titles, figure files
    named `prefix` + name."""
    from lava_bridge_mj.eval.config import METHODS

    lines: list[str] = []

    def add_figure(name: str, title: str, chosen: list[Group], about: str, skipped: str,
                   wanted: tuple[str, ...] = ()) -> None:
        lines.extend(["", f"{heading} {title}", ""])
        if not chosen:
            lines.append(f"*Skipped: {skipped}*")
            return
        save_figure(curves_figure(chosen, curves, title), out, prefix + name)
        lines.append(about)
        missing = [m for m in wanted if m not in {g.method for g in chosen}]
        if missing:
            lines.append(f"Not in this directory: {', '.join(missing)}.")
        lines.extend(["", f"![{title}]({prefix}{name}.png)", "", f"[PDF]({prefix}{name}.pdf)"])

    add_figure("benchmark", "Benchmark comparison", benchmark_groups(groups),
               "Every method, with 0.5K demo transitions where it has runs with them.", "no runs.", METHODS)
    add_figure("demo_size", "Demo-size study: 0.5K vs 7.5K", demo_size_groups(groups),
               "The methods with runs on both demo sets; solid lines 0.5K, dashed 7.5K.",
               "no method has runs with both 0.5K and 7.5K demo transitions.")
    add_figure("start_distributions", "Start-distribution study", benchmark_groups(groups, START_STUDY),
               "SAC trained from each start-state distribution over the same candidate demo states.",
               f"none of {', '.join(START_STUDY)} has runs here.", START_STUDY)
    lines.extend(["", f"{heading} The maze and AuxSS's start weights", "",
                  *_maze_section(groups, threshold, where, out, warnings, prefix + "maze")])
    lines.extend(["", f"{heading} At the last evaluation", "", *_last_evaluation_table(groups, curves)])
    lines.extend(["", f"{heading} Over the last third of training", "", *_late_table(groups, reps)])
    lines.extend(["", f"{heading} Steps to p0 success >= {threshold:g}", "", *_threshold_table(groups, threshold)])
    lines.extend(["", f"{heading} Seeds reaching p0 success >= {threshold:g}", "", *_reach_table(groups, threshold)])
    lines.extend(["", f"{heading} Pairwise tests", "", *_pairwise_section(groups, threshold)])
    if threshold == THRESHOLD and groups[0].task == DEFAULT_ENV_ID:  # the paper's claims: 0.8, its maze
        lines.extend(["", f"{heading} The paper's findings", "", *_findings_section(groups, heading)])
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="lava-bridge-bench report",
        description="Regenerate the paper's figures (PNG and PDF) and a Markdown report with IQM/CI tables "
                    "from a directory of runs (found at any depth by config.json and metrics.csv).")
    parser.add_argument("dirs", metavar="DIR", type=Path, nargs="+",
                        help="directory holding runs, e.g. a sweep's output; several are reported together")
    parser.add_argument("--out", type=Path, default=None, help="where to write the figures and report.md "
                        "(default: DIR/report of the first DIR)")
    parser.add_argument("--threshold", type=float, default=THRESHOLD,
                        help="p0 success that counts as solved, for steps-to-threshold (default: %(default)s)")
    parser.add_argument("--reps", type=int, default=BOOTSTRAP_REPS,
                        help=f"bootstrap resamples per confidence interval, 1-{MAX_REPS:,} (default: %(default)s)")
    parser.add_argument("--budget", type=_positive_int, default=None,
                        help="only evaluations at or before this step, e.g. 100000 to compare runs extended to "
                             "300000 with runs stopped at 100000 (default: every evaluation)")
    parser.add_argument("--seeds", type=seed_list, default=None,
                        help="only these seeds' runs, e.g. 0-4 or 0,3,5-7 (default: every run)")
    args = parser.parse_args(argv)
    if not 1 <= args.reps <= MAX_REPS:
        parser.error(f"--reps must be in 1-{MAX_REPS:,}, got {args.reps}")
    if not 0 <= args.threshold <= 1:
        parser.error(f"--threshold must be a success rate in [0, 1], got {args.threshold}")
    out = args.out if args.out is not None else args.dirs[0] / "report"
    unwritable = _unwritable(out)
    if unwritable:
        return _error(f"--out {out} {unwritable}")
    try:
        runs = [run for root in args.dirs for run in find_runs(root, args.budget, args.seeds)]  # before writing
        group_runs(runs)  # refuses a seed given twice
    except ValueError as error:
        return _error(str(error))
    unchanged = f"{out} is left as it was" if out.exists() else "nothing written"
    previous = signal.signal(signal.SIGTERM, _interrupt) if _in_main_thread() else None
    try:
        report = build_report(args.dirs, out, args.threshold, args.reps, runs, args.budget, args.seeds)
    except ValueError as error:  # a run's files cannot be used (its config makes no maze, ...)
        return _error(f"{error}; {unchanged}")
    except OSError as error:  # a full disk, a directory that turned read-only, ...
        return _error(f"cannot write the report into {out}: {error.strerror or error} ({error.filename}); "
                      f"{unchanged}")
    except KeyboardInterrupt:
        return _error(f"interrupted; {unchanged}", code=130)
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
    print(f"wrote {report} and its figures from {len(runs)} runs")
    return 0


def _unwritable(out: Path) -> str | None:
    """Why files cannot be written into directory `out` (to be made where missing), or None."""
    if out.exists() and not out.is_dir():
        return "exists and is not a directory"
    existing = nearest_existing(out)
    if not existing.is_dir():
        return f"cannot be made: {existing} is not a directory"
    if not os.access(existing, os.W_OK | os.X_OK):
        return f"cannot be written: {existing} is not a writable directory" if existing == out else \
            f"cannot be made: {existing} is not a writable directory"
    return None


def _error(message: str, code: int = 2) -> int:
    print(f"lava-bridge-bench report: error: {message}", file=sys.stderr)
    return code


if __name__ == "__main__":
    sys.exit(main())
