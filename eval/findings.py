"""The paper's findings on Lava Bridge, each checked against a fixed criterion on the runs at hand.

`check_findings(groups)` returns one `Finding` per claim of the paper (findings 1-6), with the
numbers it rests on and a verdict: *reproduced*, *partly*, *not reproduced*, or *missing runs* when a
group it needs is absent. The criteria are written down here, before and independently of any
result, as the most direct reading of the paper's words (section 5); they are deliberately simple
so a reader can redo them from the report's tables:

1. SAC from p0 "fails to reach the goal within the budget": reproduced when SAC's IQM success from
   p0 never exceeds 0.1 at any evaluation; partly when it ends at or below 0.2.
2. AuxSS (150 of the 0.5K demo states) reaches 0.8 from p0 in at most a third of the steps of the best
   of HySAC and JSRL, on either demo set: compares the median steps to 0.8 over all seeds (a seed that
   never got there counts as infinitely late). Reproduced at <= 1/3, partly when AuxSS is faster but
   not 3x, not reproduced otherwise (and when AuxSS's median is never reached).
3. HySAC+AuxSS is at least as robust as either alone: IQM success from ood at the last common
   evaluation. Reproduced when >= both AuxSS's and HySAC's, partly when >= one of them.
4. Omega-SS matches AuxSS early and its ood success falls behind later: "early" is the first half
   of the evaluations (long enough for AuxSS to leave 0), where Omega-SS's mean IQM success from p0
   (the area under its curve) must be at least AuxSS's minus 0.1;
   "later" is the last evaluation, where its IQM success from ood must be below AuxSS's. Reproduced
   when both hold, partly when one does.
5. U-SS and GoalDist-SS are clearly slower than AuxSS and Omega-SS: each one's median steps to 0.8 is
   later than both AuxSS's and Omega-SS's (and those two are reached). Reproduced when both U-SS and
   GoalDist-SS are, partly when one is.
6. IQL does well from p0 and drops from ood; BC fails from both with 0.5K demos: IQL's last IQM success
   from p0 >= 0.8 and from ood at least 0.1 below it; BC's last IQM success <= 0.2 from both.
   Reproduced when both parts hold, partly when one does.

`demo_size_rows` and `variant_rows` tabulate findings 7 (0.5K vs 7.5K) and 8 (the AuxSS ablations),
which the paper states as comparisons to look at rather than as pass/fail claims.

Groups are taken in their default configuration: a group whose settings (eval/aggregate.py) differ
from RunConfig's defaults is a variant (an ablation, a LayerNorm critic) and never stands in for its
method in findings 1-6. The online groups are first cut to the last evaluation step all of them have
(`common_step`), so no claim compares one method at 50,000 steps with another at 100,000 (offline
methods count gradient steps and are left as they are). Values are IQMs across seeds at each step
(eval/aggregate.py's `iqm`, the report's curves without their intervals).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from lava_bridge_mj.agents.methods import METHODS
from lava_bridge_mj.eval.aggregate import Group, demos_label, groups_of, iqm, steps_to_threshold

REPRODUCED, PARTLY, NOT, MISSING = "reproduced", "partly", "not reproduced", "missing runs"
TOLERANCE = 1e-9
"""IQMs of success rates are sums of fifties: 0.1 may come out as 0.10000000000000002."""
HYBRIDS = ("hysac", "jsrl")


@dataclasses.dataclass(frozen=True)
class Finding:
    number: int
    claim: str
    measured: str
    verdict: str


def is_default(group: Group) -> bool:
    """True when every setting that sets the group apart is RunConfig's default."""
    return not group.changed_settings


def pick(groups: list[Group], method: str, demos: int = 500) -> Group | None:
    """The method's group on that demo set in its default configuration; None if there is none."""
    return next((g for g in groups_of(groups, method, demos) if is_default(g)), None)


def common_step(groups: list[Group]) -> float | None:
    """The last evaluation step every online group has, when some group has evaluated further (the
    findings then stop there); None when they all end at the same step."""
    ends = {g.steps[-1] for g in groups if METHODS[g.method].online and len(g.steps)}
    return min(ends) if len(ends) > 1 else None


def _cut(groups: list[Group], step: float | None) -> list[Group]:
    if step is None:
        return groups
    return [g if not METHODS[g.method].online else dataclasses.replace(g, runs=[
        dataclasses.replace(run, rows=[row for row in run.rows if row["step"] <= step]) for run in g.runs])
        for g in groups]


def _curve(group: Group, metric: str) -> np.ndarray:
    """IQM across seeds at each of the group's common steps."""
    return iqm(group.scores(metric))


def _last(group: Group, metric: str) -> float:
    curve = _curve(group, metric)
    return float(curve[-1]) if len(curve) else math.nan


def _median_steps(group: Group) -> float:
    return steps_to_threshold(group).median


def _steps_text(group: Group) -> str:
    found = steps_to_threshold(group)
    median = f"{found.median:,.0f}" if math.isfinite(found.median) else "never"
    return f"{group.label}: median {median} ({found.reached} of {len(group.runs)} seeds reach 0.8)"


def _missing(claim: str, number: int, names: list[str]) -> Finding:
    return Finding(number, claim, "no runs of " + ", ".join(names), MISSING)


def _require(groups: list[Group], methods: tuple[str, ...]) -> tuple[dict[str, Group], list[str]]:
    """The default 0.5K group of each method, and the names of those that have none."""
    chosen = {m: pick(groups, m) for m in methods}
    return chosen, [f"{m} (0.5K)" for m, g in chosen.items() if g is None]


def _grade(passed: int, needed: int) -> str:
    return REPRODUCED if passed == needed else PARTLY if passed else NOT


def sac_fails(groups) -> Finding:
    claim = "SAC from p0 stays near 0% success within the budget"
    sac = pick(groups, "sac")
    if sac is None:
        return _missing(claim, 1, ["sac (0.5K)"])
    p0, steps = _curve(sac, "success_p0"), sac.steps
    peak, last = float(np.nanmax(p0)), float(p0[-1])
    verdict = REPRODUCED if peak <= 0.1 + TOLERANCE else PARTLY if last <= 0.2 + TOLERANCE else NOT
    measured = (f"IQM success from p0: at most {peak:.2f} over {len(steps)} evaluations to step "
                f"{steps[-1]:,.0f}, {last:.2f} at the last; {steps_to_threshold(sac).reached} of "
                f"{len(sac.runs)} seeds ever reach 0.8")
    return Finding(1, claim, measured, verdict)


def auxss_faster_than_hybrids(groups) -> Finding:
    claim = "AuxSS reaches 0.8 from p0 in at most 1/3 of the steps of the best of HySAC and JSRL (0.5K or 7.5K)"
    auxss = pick(groups, "auxss")
    hybrids = [g for g in (pick(groups, m, d) for m in HYBRIDS for d in (500, 7500)) if g is not None]
    absent = [f"{m} ({demos_label(d)})" for m in HYBRIDS for d in (500, 7500) if pick(groups, m, d) is None]
    if auxss is None or not hybrids:
        return _missing(claim, 2, (["auxss (0.5K)"] if auxss is None else []) + absent)
    mine, best = _median_steps(auxss), min(_median_steps(g) for g in hybrids)
    if not math.isfinite(mine):
        verdict = NOT
    else:
        verdict = REPRODUCED if mine <= best / 3 else PARTLY if mine < best else NOT
    ratio = f"; ratio {mine / best:.2f}" if math.isfinite(mine) and math.isfinite(best) else ""
    measured = "; ".join(_steps_text(g) for g in [auxss, *hybrids]) + ratio
    if absent:
        measured += f"; not run: {', '.join(absent)}"
    return Finding(2, claim, measured, verdict)


def hybrid_auxss_most_robust(groups) -> Finding:
    claim = "HySAC+AuxSS is at least as robust (success from ood) as AuxSS and HySAC alone"
    chosen, absent = _require(groups, ("hysac_auxss", "auxss", "hysac"))
    if absent:
        return _missing(claim, 3, absent)
    ood = {m: _last(g, "success_ood") for m, g in chosen.items()}
    passed = sum(ood["hysac_auxss"] >= ood[m] - TOLERANCE for m in ("auxss", "hysac"))
    measured = "IQM success from ood at the last evaluation: " + ", ".join(
        f"{chosen[m].label} {ood[m]:.2f}" for m in chosen)
    return Finding(3, claim, measured, _grade(passed, 2))


def omega_early_then_behind(groups) -> Finding:
    claim = "Omega-SS matches AuxSS early in training; its ood success falls behind AuxSS later"
    chosen, absent = _require(groups, ("omega_ss", "auxss"))
    if absent:
        return _missing(claim, 4, absent)
    omega, auxss = chosen["omega_ss"], chosen["auxss"]
    steps = np.intersect1d(omega.steps, auxss.steps)
    early = steps[:max(1, len(steps) // 2)]

    def mean_p0(group):
        return float(np.mean(_curve(group, "success_p0")[np.isin(group.steps, early)]))

    early_omega, early_auxss = mean_p0(omega), mean_p0(auxss)
    late_omega, late_auxss = _last(omega, "success_ood"), _last(auxss, "success_ood")
    passed = (early_omega >= early_auxss - 0.1 - TOLERANCE) + (late_omega < late_auxss - TOLERANCE)
    measured = (f"mean IQM success from p0 over the first {len(early)} evaluations (to step {early[-1]:,.0f}): "
                f"Omega-SS {early_omega:.2f}, AuxSS {early_auxss:.2f}; IQM success from ood at the last: "
                f"Omega-SS {late_omega:.2f}, AuxSS {late_auxss:.2f}")
    return Finding(4, claim, measured, _grade(passed, 2))


def undirected_starts_slower(groups) -> Finding:
    claim = "U-SS and GoalDist-SS are clearly slower than AuxSS and Omega-SS"
    chosen, absent = _require(groups, ("uniform_ss", "goaldist_ss", "auxss", "omega_ss"))
    if absent:
        return _missing(claim, 5, absent)
    median = {m: _median_steps(g) for m, g in chosen.items()}
    safety_based = max(median["auxss"], median["omega_ss"])  # slower must mean later than both
    passed = sum(math.isfinite(safety_based) and median[m] > safety_based for m in ("uniform_ss", "goaldist_ss"))
    measured = "; ".join(_steps_text(g) for g in chosen.values())
    return Finding(5, claim, measured, _grade(passed, 2))


def offline_methods(groups) -> Finding:
    claim = "IQL does well from p0 and drops from ood; BC fails from both with 0.5K demos"
    chosen, absent = _require(groups, ("iql", "bc"))
    if absent:
        return _missing(claim, 6, absent)
    values = {(m, k): _last(g, f"success_{k}") for m, g in chosen.items() for k in ("p0", "ood")}
    iql_part = values["iql", "p0"] >= 0.8 - TOLERANCE and values["iql", "ood"] <= values["iql", "p0"] - 0.1 + TOLERANCE
    bc_part = values["bc", "p0"] <= 0.2 + TOLERANCE and values["bc", "ood"] <= 0.2 + TOLERANCE
    measured = (f"IQM success at the last evaluation, p0 / ood: IQL {values['iql', 'p0']:.2f} / "
                f"{values['iql', 'ood']:.2f}, BC {values['bc', 'p0']:.2f} / {values['bc', 'ood']:.2f}")
    return Finding(6, claim, measured, _grade(iql_part + bc_part, 2))


CHECKS = (sac_fails, auxss_faster_than_hybrids, hybrid_auxss_most_robust, omega_early_then_behind,
          undirected_starts_slower, offline_methods)


def check_findings(groups: list[Group]) -> list[Finding]:
    """Findings 1-6 on these groups, the online ones cut to their common last step."""
    groups = _cut(groups, common_step(groups))
    return [check(groups) for check in CHECKS]


def _summary_row(group: Group) -> str:
    found = steps_to_threshold(group)
    median = f"{found.median:,.0f}" if math.isfinite(found.median) else "never"
    return (f"| {group.label} | {len(group.runs)} | {found.reached} | {median} | "
            f"{_last(group, 'success_p0'):.2f} | {_last(group, 'success_ood'):.2f} |")


SUMMARY_HEADER = ["| group | seeds | seeds reaching 0.8 | median steps to 0.8 | IQM p0 at the last | IQM ood at the last |",
                  "|---|---:|---:|---:|---:|---:|"]


def demo_size_rows(groups: list[Group]) -> list[str]:
    """Finding 7: every default-configuration method with runs on both demo sets, 0.5K beside 7.5K
    (online groups cut to their common last step)."""
    groups, rows = _cut(groups, common_step(groups)), []
    for method in dict.fromkeys(g.method for g in groups):
        pair = [pick(groups, method, d) for d in (500, 7500)]
        if all(pair):
            rows += [_summary_row(g) for g in pair]
    return SUMMARY_HEADER + rows if rows else []


def variant_rows(groups: list[Group], method: str = "auxss") -> list[str]:
    """Finding 8: the method's default group (0.5K) and each of its variants (ablations), online
    groups cut to their common last step."""
    groups = _cut(groups, common_step(groups))
    base = pick(groups, method)
    variants = [g for g in groups_of(groups, method, 500) if not is_default(g)]
    if base is None or not variants:
        return []
    return SUMMARY_HEADER + [_summary_row(g) for g in [base, *variants]]
