"""Recompute the study's verdicts from results/study alone, without importing lava_bridge_mj.

An auditor's check of the rules docs/results.md states ("How a verdict is read"), written apart from the
package: its own reading of the metrics files, its own exact tests (integer subset counts with Python's
big integers where the package uses floats), analytic equivalence tests where the package inverts
intervals numerically, and Pocock's two-look level from scipy's bivariate normal where the package
integrates by quadrature. It prints, per task and question, the verdict of every comparison as JSON.

    python tests/outside/recompute_study.py results/study --seeds 0-48 --looks 20,49

--task-seeds TASK=FIRST-LAST (repeatable) reads that task at its own seeds, as the study report does for a
task whose seed extension is still training.
"""

import argparse
import csv
import json
import math
from collections import Counter
from fractions import Fraction
from pathlib import Path

import numpy as np
import scipy.optimize
import scipy.stats

THRESHOLD, ROBUST, MARGIN, ALPHA = 0.8, 0.5, 0.3, 0.05
QUESTIONS = {1: [(a, b) for a in ("auxss", "omega_ss") for b in ("uniform_ss", "goaldist_ss")],
             2: [("auxss", "rfcl")]}
STAND_IN = {"rfcl": "reverse_ss"}  # a task without runs of RFCL as published reads its reverse curriculum


def read_group(folder: Path, seeds: set[int]) -> dict[int, list[dict[str, float]]]:
    runs = {}
    for run in sorted(folder.glob("seed*")):
        seed = int(run.name[4:])
        if seed in seeds and (run / "metrics.csv").is_file():
            with open(run / "metrics.csv") as f:
                runs[seed] = [{k: float(v) for k, v in row.items() if k in ("step", "success_p0", "success_ood")}
                              for row in csv.DictReader(f)]
    return runs


def common_steps(runs: dict) -> list[float]:
    return sorted(set.intersection(*({row["step"] for row in rows} for rows in runs.values())))


def outcomes(a: dict, b: dict) -> tuple[dict, dict]:
    """Per side, per matched seed: first step at p0 success >= 0.8 (inf: never) and mean late ood success."""
    seeds = sorted(set(a) & set(b))
    a, b = ({s: g[s] for s in seeds} for g in (a, b))
    step = min(common_steps(a)[-1], common_steps(b)[-1])
    result = []
    for group in (a, b):
        group = {s: [row for row in rows if row["step"] <= step] for s, rows in group.items()}
        steps = common_steps(group)
        window = [t for t in steps if t > (1 - 1 / 3) * steps[-1]]
        first, late = [], []
        for rows in group.values():
            hits = [row["step"] for row in rows if row["step"] <= steps[-1] and row["success_p0"] >= THRESHOLD]
            first.append(min(hits) if hits else math.inf)
            by_step = {row["step"]: row["success_ood"] for row in rows}
            late.append(float(np.mean([by_step[t] for t in window])))
        result.append({"first": np.array(first), "late": np.array(late)})
    return result[0], result[1]


def exact_two_sided(x: np.ndarray, y: np.ndarray) -> float:
    """Twice the smaller tail of the sum of x over all splits of the pooled values, counted exactly."""
    pooled = [Fraction(float(v)).limit_denominator(10**6) for v in np.concatenate([x, y])]
    scale = math.lcm(*(v.denominator for v in pooled))
    scores = [int(v * scale) for v in pooled]
    low = min(scores)
    scores = [s - low for s in scores]
    n = len(x)
    ways = [dict() for _ in range(n + 1)]  # ways[k][sum] = number of k-subsets with that sum
    ways[0][0] = 1
    for score, many in Counter(scores).items():  # choose j of the `many` equal scores: C(many, j) ways
        grown = [dict(w) for w in ways]
        for k in range(n):
            for total, count in ways[k].items():
                for j in range(1, min(many, n - k) + 1):
                    key = total + j * score
                    grown[k + j][key] = grown[k + j].get(key, 0) + count * math.comb(many, j)
        ways = grown
    observed = sum(scores[:n])
    splits = math.comb(len(scores), n)
    less = sum(c for t, c in ways[n].items() if t <= observed)
    greater = sum(c for t, c in ways[n].items() if t >= observed)
    return min(1.0, 2 * min(less, greater) / splits)


def rank_p(x: np.ndarray, y: np.ndarray) -> float:
    both = np.concatenate([x, y])
    if np.all(both == both[0]):
        return 1.0
    finite = both[np.isfinite(both)]
    ranks = scipy.stats.rankdata(np.where(np.isfinite(both), both, (finite.max() if len(finite) else 0) + 1))
    return exact_two_sided(ranks[:len(x)], ranks[len(x):])


def perm_p(x: np.ndarray, y: np.ndarray) -> float:
    return 1.0 if np.all(np.concatenate([x, y]) == x[0]) else exact_two_sided(x, y)


def holm(p: list[float]) -> list[float]:
    order = sorted(range(len(p)), key=lambda i: p[i])
    adjusted, running = [0.0] * len(p), 0.0
    for rank, i in enumerate(order):
        running = max(running, min(1.0, p[i] * (len(p) - rank)))
        adjusted[i] = running
    return adjusted


def newcombe(k1, n1, k2, n2, confidence):
    z = scipy.stats.norm.ppf(1 - (1 - confidence) / 2)

    def wilson(k, n):
        p = k / n
        centre, half = (p + z * z / (2 * n)) / (1 + z * z / n), z / (1 + z * z / n) * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
        return centre - half, centre + half

    (l1, u1), (l2, u2) = wilson(k1, n1), wilson(k2, n2)
    d = k1 / n1 - k2 / n2
    return d - math.sqrt((k1 / n1 - l1) ** 2 + (u2 - k2 / n2) ** 2), d + math.sqrt((u1 - k1 / n1) ** 2 + (k2 / n2 - l2) ** 2)


def tost_rate(k1, n1, k2, n2) -> float:
    d = k1 / n1 - k2 / n2
    if abs(d) >= MARGIN:
        return 1.0
    inside = lambda alpha: max(-MARGIN - newcombe(k1, n1, k2, n2, 1 - 2 * alpha)[0],  # noqa: E731
                               newcombe(k1, n1, k2, n2, 1 - 2 * alpha)[1] - MARGIN) < 0
    low, high = 1e-13, 0.5 - 1e-13  # inside(high) holds: the interval shrinks to the estimate
    if inside(low):
        return low
    for _ in range(200):
        middle = (low + high) / 2
        low, high = (low, middle) if inside(middle) else (middle, high)
    return high


def tost_t(estimate, error, freedom) -> float:
    if abs(estimate) >= MARGIN:
        return 1.0
    if error == 0:
        return 0.0
    return max(scipy.stats.t.sf((estimate + MARGIN) / error, freedom), scipy.stats.t.sf((MARGIN - estimate) / error, freedom))


def cliffs_delta(x, y):
    """P(x < y) - P(x > y) with Brunner-Munzel's standard error and degrees of freedom."""
    finite = np.concatenate([x, y])
    finite = finite[np.isfinite(finite)]
    ceiling = (finite.max() if len(finite) else 0) + 1
    x, y = np.where(np.isfinite(x), x, ceiling), np.where(np.isfinite(y), y, ceiling)
    delta = np.mean(np.sign(y[None, :] - x[:, None]))
    n1, n2 = len(x), len(y)
    ranks = scipy.stats.rankdata(np.concatenate([x, y]))
    s1 = np.var(ranks[:n1] - scipy.stats.rankdata(x), ddof=1)
    s2 = np.var(ranks[n1:] - scipy.stats.rankdata(y), ddof=1)
    pooled = n1 * s1 + n2 * s2
    error = 2 * math.sqrt(pooled) / (n1 * n2)
    freedom = pooled ** 2 / ((n1 * s1) ** 2 / (n1 - 1) + (n2 * s2) ** 2 / (n2 - 1)) if pooled else math.inf
    return delta, error, freedom


def welch(x, y):
    v1, v2 = np.var(x, ddof=1) / len(x), np.var(y, ddof=1) / len(y)
    freedom = (v1 + v2) ** 2 / (v1 ** 2 / (len(x) - 1) + v2 ** 2 / (len(y) - 1)) if v1 + v2 else math.inf
    return float(np.mean(x) - np.mean(y)), math.sqrt(v1 + v2), freedom


def two_look_level(first: int, second: int) -> float:
    r = math.sqrt(first / second)
    both = scipy.stats.multivariate_normal([0, 0], [[1, r], [r, 1]])

    def overall(c):  # P(|Z1| > c or |Z2| > c)
        inside = both.cdf([c, c]) - both.cdf([-c, c]) - both.cdf([c, -c]) + both.cdf([-c, -c])
        return 1 - inside - ALPHA

    return float(2 * scipy.stats.norm.sf(scipy.optimize.brentq(overall, 1.5, 4, xtol=1e-10)))


def answer(groups: dict, level: float) -> dict[int, list[dict]]:
    answers = {}
    for number, pairs in QUESTIONS.items():
        pairs = [(a, b if b in groups else STAND_IN.get(b, b)) for a, b in pairs]
        if not any(a in groups and b in groups for a, b in pairs):
            continue
        made = []
        for a, b in pairs:
            for aspect in ("learns faster", "more robust"):
                if a not in groups or b not in groups:
                    made.append({"a": a, "b": b, "aspect": aspect, "p": [1.0, 1.0], "ahead": [None, None], "tost": 1.0})
                    continue
                x, y = outcomes(groups[a], groups[b])
                if aspect == "learns faster":
                    counts = (int(np.isfinite(x["first"]).sum()), len(x["first"]), int(np.isfinite(y["first"]).sum()), len(y["first"]))
                    second_p, second = rank_p(x["first"], y["first"]), cliffs_delta(x["first"], y["first"])
                else:
                    counts = (int((x["late"] >= ROBUST - 1e-9).sum()), len(x["late"]), int((y["late"] >= ROBUST - 1e-9).sum()), len(y["late"]))
                    second_p, second = perm_p(x["late"], y["late"]), welch(x["late"], y["late"])
                rate = counts[0] / counts[1] - counts[2] / counts[3]
                fisher = scipy.stats.fisher_exact([[counts[0], counts[1] - counts[0]], [counts[2], counts[3] - counts[2]]]).pvalue
                sign = lambda v: None if abs(v) <= 1e-9 else v > 0  # noqa: E731
                made.append({"a": a, "b": b, "aspect": aspect, "p": [fisher, second_p],
                             "ahead": [sign(rate), sign(second[0])], "tost": max(tost_rate(*counts), tost_t(*second))})
        adjusted = iter(holm([p for c in made for p in c["p"]]))
        tost = holm([c["tost"] for c in made])
        for i, c in enumerate(made):
            adj = [next(adjusted), next(adjusted)]
            at = {alpha: {c["ahead"][t] for t in range(2) if adj[t] <= alpha and c["ahead"][t] is not None}
                  for alpha in (ALPHA, level)}
            if len(at[ALPHA]) == 1:
                winner = c["a"] if at[ALPHA] == {True} else c["b"]
                c["verdict"] = f"{winner} ahead" + ("" if at[level] == at[ALPHA] else f" at {ALPHA:g} only")
            else:
                c["verdict"] = "no difference found" if not at[ALPHA] and tost[i] <= level else "undecided"
        answers[number] = [{k: c[k] for k in ("a", "b", "aspect", "verdict")} for c in made if c["a"] in groups and c["b"] in groups]
    return answers


def seed_range(text: str) -> set[int]:
    """An argparse type: 'FIRST-LAST', the seeds FIRST to LAST."""
    first, dash, last = text.partition("-")
    if not (dash and first.isdigit() and last.isdigit() and int(first) <= int(last)):
        raise argparse.ArgumentTypeError(f"expected seeds as FIRST-LAST such as 0-48, got {text!r}")
    return set(range(int(first), int(last) + 1))


def task_seed_range(text: str) -> tuple[str, set[int]]:
    """An argparse type: 'TASK=FIRST-LAST'."""
    task, equals, seeds = text.partition("=")
    if not (task and equals):
        raise argparse.ArgumentTypeError(f"expected TASK=FIRST-LAST such as PointMaze_Large-v3=0-19, got {text!r}")
    return task, seed_range(seeds)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("root", type=Path)
    parser.add_argument("--seeds", type=seed_range, default="0-48", metavar="FIRST-LAST")
    parser.add_argument("--looks", default="20,49")
    parser.add_argument("--task-seeds", type=task_seed_range, action="append", default=[], metavar="TASK=FIRST-LAST")
    args = parser.parse_args()
    own_seeds = dict(args.task_seeds)
    level = two_look_level(*map(int, args.looks.split(",")))
    tasks = {}
    for task in sorted(p for p in args.root.iterdir() if p.is_dir()):
        seeds = own_seeds.get(task.name, args.seeds)
        groups = {folder.name.rsplit("-d", 1)[0]: read_group(folder, seeds)
                  for folder in task.glob("*-d500")}
        tasks[task.name] = answer({m: g for m, g in groups.items() if g}, level)
    summary = {task: {n: Counter(c["verdict"] for c in comparisons) for n, comparisons in answers.items()}
               for task, answers in tasks.items()}
    print(json.dumps({"level": level, "answers": tasks, "summary": summary}, indent=1))


if __name__ == "__main__":
    main()
