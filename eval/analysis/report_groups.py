"""Which groups go into which figure and table of the report.

Each function takes the groups of one task (eval/analysis/aggregate.py's `group_runs`, in its order) and
returns those that a figure or test uses, in that order; none draws or writes anything. Methods are
picked through `groups_of` and described by the method registry (agents/methods.py), never by a
list of names kept here.
"""

from __future__ import annotations

import math

from lava_bridge_mj.agents.methods import METHODS
from lava_bridge_mj.eval.analysis.aggregate import Group, RunRecord, groups_of, steps_to_threshold
from lava_bridge_mj.eval.analysis.claims import is_default, pick

STANDARD_DEMOS = 500
"""The paper's benchmark protocol gives every demo-using method 500 transitions (0.5K)."""
DEMO_SIZES = (500, 7500)
START_STUDY = tuple(m.name for m in METHODS.values() if m.learner == "sac" and m.demos == "none" and m.start != "p0")
"""The start-distribution study's methods (paper, figure 'ss_dists'): SAC trained from each start
strategy over the demo states, nothing else changed (auxss, omega_ss, uniform_ss and goaldist_ss on
the same random subset of them; reverse_ss, RFCL's reverse curriculum, on whole demo episodes)."""


def is_offline(group: Group) -> bool:
    """True for a method that learns from the demos alone: its steps are gradient steps."""
    method = METHODS.get(group.method)
    return method is not None and not method.online


def benchmark_groups(groups: list[Group], methods: tuple[str, ...] | None = None) -> list[Group]:
    """Per method (every one in the groups, or those of `methods`, in that order): its 0.5K groups, or
    all of its groups if it has none."""
    chosen = []
    for method in dict.fromkeys(g.method for g in groups) if methods is None else methods:
        chosen += groups_of(groups, method, STANDARD_DEMOS) or groups_of(groups, method)
    return chosen


def demo_size_groups(groups: list[Group]) -> list[Group]:
    """The groups of every method that has runs with each demo set of the study (0.5K and 7.5K)."""
    both = [m for m in dict.fromkeys(g.method for g in groups) if all(groups_of(groups, m, d) for d in DEMO_SIZES)]
    return [g for m in both for g in groups_of(groups, m) if g.demos in DEMO_SIZES]


def comparison_pairs(groups: list[Group]) -> list[tuple[Group, Group]]:
    """The pairs the report tests, each once: every pair of the start-distribution study's groups;
    AuxSS (0.5K) against every other online method's 0.5K group; each method's 0.5K against its 7.5K
    group; and each variant against its method's default configuration on the same demo set."""
    pairs: list[tuple[Group, Group]] = []

    def add(a: Group | None, b: Group | None) -> None:
        if a is not None and b is not None and a is not b and (a, b) not in pairs and (b, a) not in pairs:
            pairs.append((a, b))

    defaults = [g for g in groups if is_default(g)]
    study = [g for method in START_STUDY for g in groups_of(defaults, method, STANDARD_DEMOS)]
    for i, a in enumerate(study):
        for b in study[i + 1:]:
            add(a, b)
    for b in defaults:
        if b.demos == STANDARD_DEMOS and not is_offline(b):
            add(pick(groups, "auxss"), b)
    for g in defaults:
        if g.demos == DEMO_SIZES[0]:
            add(g, pick(groups, g.method, DEMO_SIZES[1]))
    for g in groups:
        if not is_default(g):
            add(pick(groups, g.method, g.demos), g)
    return pairs


def weights_run(groups: list[Group], threshold: float, usable=None, method: str = "auxss") -> RunRecord | None:
    """The run of `method` whose start weights a maze figure shows: of its first group (0.5K first)
    with start_weights.npz, the lowest seed that reached the threshold, else its lowest seed. `usable`
    (a run -> bool) can rule out runs whose file cannot be read."""
    for group in benchmark_groups(groups, (method,)):
        runs = [run for run in group.runs
                if (run.path / "start_weights.npz").is_file() and (usable is None or usable(run))]
        if runs:
            reached = steps_to_threshold(group, threshold).per_seed
            solved = [run for run in runs if math.isfinite(reached[run.seed])]
            return (solved or runs)[0]
    return None
