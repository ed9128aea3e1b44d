"""The paper's findings on Lava Bridge, each decided by a stated test at a stated level.

`check_findings(groups)` returns one `Finding` per claim of the paper (findings 1-8). A finding is
made of parts, each a test of one comparison or of one group alone, and every part's verdict comes
from the rules of eval/analysis/claims.py, none of which depends on the data. All online groups are first cut
to the last step every one of them has (`common_step`), and the p-values of every comparison of every
finding form one Holm family.

**A finding** whose parts must all hold (findings 1-6: a conjunction) takes the weakest of its parts'
verdicts, in the order contradicted, no difference found, undecided, supported; it is
*missing runs* when a group it needs is absent (finding 2 stands on whichever of its four baselines
were run and names the others *not run*). Findings 7 and 8 are one comparison per method or
variant, and are given per part (one verdict when all of them agree).

1. SAC from p0 stays near 0%: few seeds ever exceed `NEAR_ZERO` (0.1) success from p0 (one group).
2. AuxSS (0.5K) reaches 0.8 more often or sooner than each of HySAC and JSRL, 0.5K and 7.5K.
3. HySAC+AuxSS is at least as robust as AuxSS and as HySAC: more robust than each, tested (no
   difference found then says "as robust, not more").
4. Omega-SS matches AuxSS early: the same reach of 0.8 up to the last evaluation of the first half of
   the steps (matches); later its robustness falls behind: AuxSS more robust at the step compared.
5. U-SS and GoalDist-SS are clearly slower: AuxSS and Omega-SS each reach 0.8 more often or sooner than
   each of U-SS and GoalDist-SS (four comparisons).
6. IQL does well from p0 and drops from ood; BC fails with 0.5K (one group each, at the last
   evaluation): most IQL seeds end at success 0.8 or more from p0; most IQL seeds end at least 0.1
   lower from ood than from p0; most BC seeds end at 0.2 or less from both.
7. Demo size: each method with 7.5K demo transitions reaches 0.8 more often or sooner than with 0.5K.
8. Ablations: AuxSS as in the paper reaches 0.8 more often or sooner than each of its variants.

Groups are taken in their default configuration: a group whose settings (eval/analysis/aggregate.py) differ
from RunConfig's defaults is a variant (an ablation, a LayerNorm critic) and never stands in for its
method in findings 1-7. Offline methods count gradient steps and are left as they are.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from lava_bridge_mj.agents.methods import METHODS
from lava_bridge_mj.eval.analysis.aggregate import Group, demos_label, groups_of
from lava_bridge_mj.eval.analysis.claims import (CONTRADICTED, NO_DIFFERENCE, NOT_RUN, SUPPORTED, TOLERANCE, UNDECIDED, Part,
                                                 Pending, is_default, one_group, pick, reach_comparison, robust_comparison,
                                                 settle, until)
from lava_bridge_mj.eval.analysis.summary import THRESHOLD

NEAR_ZERO = 0.1
"""Success from p0 that a seed of a method that "stays near 0" never exceeds."""
MISSING = "missing runs"
PER_COMPARISON = "per comparison"
"""Findings 7 and 8 when their comparisons' verdicts differ: each stands alone."""
WEAKEST_FIRST = (MISSING, CONTRADICTED, NO_DIFFERENCE, UNDECIDED, SUPPORTED)
HYBRIDS = ("hysac", "jsrl")
DEMO_SIZES = (500, 7500)


@dataclasses.dataclass(frozen=True)
class Finding:
    number: int
    claim: str
    parts: list[Part]
    verdict: str

    @property
    def measured(self) -> str:
        return "; ".join(f"{p.claim}: {p.measured}" for p in self.parts)


def common_step(groups: list[Group]) -> float | None:
    """The last evaluation step every online group has, when some group has evaluated further (the
    findings then stop there); None when they all end at the same step."""
    ends = {g.steps[-1] for g in groups if METHODS[g.method].online and len(g.steps)}
    return min(ends) if len(ends) > 1 else None


def _cut(groups: list[Group], step: float | None) -> list[Group]:
    if step is None:
        return groups
    return [until(g, step) if METHODS[g.method].online else g for g in groups]


def _final(group: Group, metric: str) -> np.ndarray:
    return group.scores(metric)[:, -1]


# --- the findings ---------------------------------------------------------------------------------
@dataclasses.dataclass
class _Draft:
    number: int
    claim: str
    items: list  # Part (decided), Pending (waiting for the correction) or None (no seeds in common)
    each: bool = False
    missing: list[str] = dataclasses.field(default_factory=list)
    partial: bool = False
    """The finding stands on the groups present when some of `missing` are absent (finding 2)."""


def _absent(chosen: dict[str, Group | None]) -> list[str]:
    return [name for name, g in chosen.items() if g is None]


def _label(method: str, demos: int = 500) -> str:
    return f"{method} ({demos_label(demos)})"


def sac_fails(groups) -> _Draft:
    draft = _Draft(1, "SAC from p0 stays near 0% success within the budget", [])
    sac = pick(groups, "sac")
    if sac is None or not len(sac.steps):
        draft.missing = [_label("sac")]
        return draft
    escaped = int((np.nanmax(sac.scores("success_p0"), axis=1) > NEAR_ZERO + TOLERANCE).sum())
    draft.items.append(one_group(f"few seeds of sac exceed success {NEAR_ZERO:g} from p0 by step {sac.steps[-1]:,.0f}",
                                 escaped, len(sac.runs), few=True))
    return draft


def auxss_faster_than_hybrids(groups) -> _Draft:
    draft = _Draft(2, "AuxSS (0.5K) reaches 0.8 from p0 sooner or more often than HySAC and JSRL (0.5K and 7.5K)", [])
    auxss = pick(groups, "auxss")
    chosen = {_label(m, d): pick(groups, m, d) for m in HYBRIDS for d in DEMO_SIZES}
    if auxss is None or not any(chosen.values()):
        draft.missing = ([_label("auxss")] if auxss is None else []) + _absent(chosen)
        return draft
    for name, hybrid in chosen.items():
        if hybrid is not None:
            draft.items.append(reach_comparison(auxss, hybrid, f"auxss (0.5K) against {name}"))
    draft.missing, draft.partial = _absent(chosen), True
    return draft


def hybrid_auxss_most_robust(groups) -> _Draft:
    draft = _Draft(3, "HySAC+AuxSS is at least as robust (success from ood) as AuxSS and HySAC alone", [])
    chosen = {_label(m): pick(groups, m) for m in ("hysac_auxss", "auxss", "hysac")}
    if _absent(chosen):
        draft.missing = _absent(chosen)
        return draft
    combined = chosen["hysac_auxss (0.5K)"]
    for name in ("auxss (0.5K)", "hysac (0.5K)"):
        draft.items.append(robust_comparison(combined, chosen[name], f"hysac_auxss (0.5K) more robust than {name}"))
    return draft


def omega_early_then_behind(groups) -> _Draft:
    draft = _Draft(4, "Omega-SS matches AuxSS early in training; its ood success falls behind AuxSS later", [])
    omega, auxss = pick(groups, "omega_ss"), pick(groups, "auxss")
    if omega is None or auxss is None:
        draft.missing = _absent({_label("omega_ss"): omega, _label("auxss"): auxss})
        return draft
    steps = np.intersect1d(omega.steps, auxss.steps)
    if len(steps):
        early = steps[max(1, len(steps) // 2) - 1]
        draft.items.append(reach_comparison(until(omega, early), until(auxss, early),
                                            f"omega_ss (0.5K) matches auxss (0.5K) up to step {early:,.0f}",
                                            matches=True))
    draft.items.append(robust_comparison(auxss, omega, "auxss (0.5K) more robust than omega_ss (0.5K) later"))
    return draft


def undirected_starts_slower(groups) -> _Draft:
    draft = _Draft(5, "U-SS and GoalDist-SS are clearly slower than AuxSS and Omega-SS", [])
    chosen = {m: pick(groups, m) for m in ("auxss", "omega_ss", "uniform_ss", "goaldist_ss")}
    if _absent(chosen):
        draft.missing = [_label(m) for m in _absent(chosen)]
        return draft
    for fast in ("auxss", "omega_ss"):
        for slow in ("uniform_ss", "goaldist_ss"):
            draft.items.append(reach_comparison(chosen[fast], chosen[slow], f"{_label(fast)} against {_label(slow)}"))
    return draft


def offline_methods(groups) -> _Draft:
    draft = _Draft(6, "IQL does well from p0 and drops from ood; BC fails from both with 0.5K demos", [])
    iql, bc = pick(groups, "iql"), pick(groups, "bc")
    if iql is None or bc is None or not (len(iql.steps) and len(bc.steps)):
        draft.missing = _absent({_label("iql"): iql, _label("bc"): bc})
        return draft
    p0, ood = _final(iql, "success_p0"), _final(iql, "success_ood")
    seeds = len(iql.runs)
    bc_fails = (_final(bc, "success_p0") <= 0.2 + TOLERANCE) & (_final(bc, "success_ood") <= 0.2 + TOLERANCE)
    draft.items += [
        one_group("most seeds of iql (0.5K) end at success 0.8 or more from p0",
                  int((p0 >= THRESHOLD - TOLERANCE).sum()), seeds, few=False),
        one_group("most seeds of iql (0.5K) end at least 0.1 lower from ood than from p0",
                  int((ood <= p0 - 0.1 + TOLERANCE).sum()), seeds, few=False),
        one_group("most seeds of bc (0.5K) end at success 0.2 or less from both p0 and ood",
                  int(bc_fails.sum()), len(bc.runs), few=False)]
    return draft


def demo_size(groups) -> _Draft:
    draft = _Draft(7, "With 7.5K demo transitions a method reaches 0.8 sooner or more often than with 0.5K", [],
                   each=True)
    for method in dict.fromkeys(g.method for g in groups):
        small, large = (pick(groups, method, d) for d in DEMO_SIZES)
        if small is not None and large is not None:
            draft.items.append(reach_comparison(large, small, f"{_label(method, 7500)} against {_label(method)}"))
    if not draft.items:
        draft.missing = ["a method with both 0.5K and 7.5K runs"]
    return draft


def ablations(groups, method: str = "auxss") -> _Draft:
    draft = _Draft(8, "AuxSS as in the paper reaches 0.8 sooner or more often than each of its variants (ablations)",
                   [], each=True)
    base = pick(groups, method)
    variants = [g for g in groups_of(groups, method, 500) if not is_default(g)]
    if base is None or not variants:
        draft.missing = ([_label(method)] if base is None else []) + ([] if variants else [f"a variant of {method}"])
        return draft
    for variant in variants:
        draft.items.append(reach_comparison(base, variant, f"{base.label} against {variant.label}"))
    return draft


CHECKS = (sac_fails, auxss_faster_than_hybrids, hybrid_auxss_most_robust, omega_early_then_behind,
          undirected_starts_slower, offline_methods, demo_size, ablations)


def _no_common_seeds(claim: str) -> Part:
    return Part(claim, "the groups share no seed or evaluation step", MISSING)


def check_findings(groups: list[Group]) -> list[Finding]:
    """Findings 1-8 on these groups, the online ones cut to their common last step, every comparison's
    p-values corrected as one family."""
    groups = _cut(groups, common_step(groups))
    drafts = [check(groups) for check in CHECKS]
    pending = [item for d in drafts for item in d.items if isinstance(item, Pending)]
    settled = iter(settle(pending))
    findings = []
    for d in drafts:
        parts = [next(settled) if isinstance(item, Pending) else item if item is not None
                 else _no_common_seeds(d.claim) for item in d.items]
        if d.missing:
            absent = NOT_RUN if parts and d.partial else MISSING
            parts.append(Part("groups not run", ", ".join(d.missing), absent))
        verdicts = [p.verdict for p in parts if p.verdict != NOT_RUN]
        if d.each and len(set(verdicts)) > 1 and MISSING not in verdicts:
            verdict = PER_COMPARISON
        else:
            verdict = min(verdicts, key=WEAKEST_FIRST.index) if verdicts else MISSING
        findings.append(Finding(d.number, d.claim, parts, verdict))
    return findings
