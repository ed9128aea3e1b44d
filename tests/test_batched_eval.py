"""Batched evaluation (eval/training/evaluate.py) against the per-seed loop it replaced: every member of a
seed-batched agent evaluated on its own, one single env per episode, stepped one by one."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

import lava_bridge_mj
from lava_bridge_mj.agents.sac import SACConfig
from lava_bridge_mj.eval.training import evaluate as evaluate_module
from lava_bridge_mj.eval.training.config import RunConfig
from lava_bridge_mj.eval.training.evaluate import EVAL_SEED, OWN_CALL_ROWS, evaluate
from lava_bridge_mj.eval.training.runner import make_agent
from lava_bridge_mj.vector import LavaBridgeVectorEnv

ENV = {"step_reward": -0.01, "lava_reward": -1.0}
"""Rewards that tell lava, goal and time-limit endings apart in the returns."""


def reference_evaluate(policy, envs, start, horizon):
    """The per-seed evaluation as it ran before batching: `policy` maps (n, 4) -> (n, 2)."""
    n = len(envs)
    obs = np.stack([env.reset(seed=EVAL_SEED + i, options={"start": start})[0] for i, env in enumerate(envs)])
    running, returns, success = np.ones(n, dtype=bool), np.zeros(n), np.zeros(n, dtype=bool)
    endings = []
    for _ in range(horizon):
        active = np.flatnonzero(running)
        if active.size == 0:
            break
        actions = policy(obs[active])
        if not np.isfinite(actions).all():
            return None, endings
        for action, i in zip(actions, active):
            obs[i], reward, terminated, _, info = envs[i].step(action)
            returns[i] += reward
            if terminated:
                running[i] = False
                success[i] = info["is_success"]
                endings.append("goal" if info["is_success"] else "lava")
    endings += ["time limit"] * int(running.sum())
    return {"success": float(success.mean()), "return": float(returns.mean())}, endings


class ScriptedMembers:
    """A stand-in for a seed-batched agent whose member k acts with policies[k], row by row."""

    def __init__(self, policies):
        self.policies = policies
        self.num_seeds = len(policies)

    def act(self, obs, deterministic=False):
        assert deterministic
        return np.stack([np.stack([policy(o) for o in member_obs]) for policy, member_obs in zip(self.policies, obs)])

    def policy(self, k):
        return lambda obs: np.stack([self.policies[k](o) for o in obs])


def config(hidden=(16, 16)):
    return RunConfig(method="auxss", seed=0, sac=SACConfig(hidden_sizes=hidden), env=ENV)


def test_goal_lava_and_time_limit_episodes_score_as_in_the_per_seed_loop():
    """The expert (at three times its force) reaches the goal, a full push to the right runs into the first lava pit (or, from
    one p0 start, into a wall until the time limit), a push into a corner runs to the time limit:
    each member's success and return equal the per-seed loop's, from p0 and ood, whichever way the
    members are grouped into the vector env."""
    expert = lava_bridge_mj.ScriptedExpert()
    fast_expert = lambda o: np.clip(3 * expert.act(o), -1, 1).astype(np.float32)  # noqa: E731
    agent = ScriptedMembers([fast_expert, lambda o: np.float32([1.0, 0.0]), lambda o: np.float32([-1.0, 0.3])])
    episodes, horizon = 4, 170
    singles = [config().make_env() for _ in range(episodes)]
    endings = set()
    for start in ("p0", "ood"):
        expected = {}
        for k in range(agent.num_seeds):
            expected[k], ends = reference_evaluate(agent.policy(k), singles, start, horizon)
            endings.update(ends)
        for members_at_once in (3, 1):
            envs = LavaBridgeVectorEnv(members_at_once * episodes + 1, **config().env_kwargs())
            assert evaluate(agent, envs, start, episodes, horizon=horizon) == (expected, {})
    assert endings == {"goal", "lava", "time limit"}


@pytest.mark.parametrize("hidden", [(16, 16), (64, 64)])
def test_untrained_actors_score_as_in_the_per_seed_loop(hidden):
    """Real stacked actors, whose episodes end at different steps, so the members' row counts part."""
    torch.manual_seed(0)
    agent = make_agent(config(hidden), seeds=[0, 1, 2])
    episodes, horizon = 5, 60
    singles = [config().make_env() for _ in range(episodes)]
    envs = LavaBridgeVectorEnv(3 * episodes, **config().env_kwargs())
    for start in ("p0", "ood"):
        expected = {k: reference_evaluate(agent.policy(k), singles, start, horizon)[0] for k in range(3)}
        assert evaluate(agent, envs, start, episodes, horizon=horizon) == (expected, {})


@pytest.mark.parametrize("hidden", [(8, 8), (16, 16), (64, 64)])
def test_each_members_actions_equal_its_own_call_for_any_mix_of_row_counts(hidden):
    """torch rounds small products differently from large ones, so a member's rows must be computed
    as its own call computes them: every count from 1 to past OWN_CALL_ROWS, members side by side."""
    counts = [1, 2, 3, 5, 6, 7, 12, 13, OWN_CALL_ROWS - 1, OWN_CALL_ROWS, OWN_CALL_ROWS + 1, 40]
    agent = make_agent(config(hidden), seeds=list(range(len(counts))))
    rng = np.random.default_rng(1)
    obs = rng.uniform(-3.0, 3.0, (sum(counts), 4))
    owners = np.repeat(np.arange(len(counts)), counts)
    batched = evaluate_module._act(agent, obs, owners)
    for k in range(len(counts)):
        assert np.array_equal(batched[owners == k], agent.policy(k)(obs[owners == k])), f"member {k}, {counts[k]} rows"


def test_the_own_call_limit_is_needed(monkeypatch):
    """Without calls of a member's own row count, a member with a few rows rounds differently: the
    test above would catch a batching that ignores it."""
    monkeypatch.setattr(evaluate_module, "OWN_CALL_ROWS", 1)
    counts = [2, 40]
    agent = make_agent(config((16, 16)), seeds=[0, 1])
    obs = np.random.default_rng(1).uniform(-3.0, 3.0, (sum(counts), 4))
    owners = np.repeat([0, 1], counts)
    assert not np.array_equal(evaluate_module._act(agent, obs, owners)[:2], agent.policy(0)(obs[:2]))


def test_a_member_whose_actions_are_not_finite_stops_alone():
    """Member 1's actor is NaN: it is reported as diverged, naming its action; the others score as alone."""
    agent = make_agent(config(), seeds=[0, 1, 2])
    with torch.no_grad():
        for parameter in agent.actor.parameters():
            parameter[1] = float("nan")
    episodes, horizon = 3, 40
    singles = [config().make_env() for _ in range(episodes)]
    envs = LavaBridgeVectorEnv(3 * episodes, **config().env_kwargs())
    scores, diverged = evaluate(agent, envs, "p0", episodes, horizon=horizon)
    assert set(scores) == {0, 2} and set(diverged) == {1}
    assert diverged[1] == "its evaluation policy's actions are not finite ([nan nan])"
    for k in (0, 2):
        assert scores[k] == reference_evaluate(agent.policy(k), singles, "p0", horizon)[0]
    assert evaluate(agent, envs, "p0", episodes, members=[2], horizon=horizon) == ({2: scores[2]}, {})


def test_too_small_a_vector_env_is_refused():
    agent = make_agent(config(), seeds=[0])
    with pytest.raises(ValueError, match="5 episodes need 5 sub-envs, the vector env has 4"):
        evaluate(agent, LavaBridgeVectorEnv(4, **config().env_kwargs()), "p0", 5)


def test_the_benchmark_runs_and_finds_both_ways_equal():
    bench = Path(__file__).resolve().parent.parent / "bench" / "eval_round.py"
    result = subprocess.run([sys.executable, str(bench), "--quick"], capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr
    rows = [line for line in result.stdout.splitlines() if line.startswith(("untrained", "BC actors"))]
    assert len(rows) == 2 and all(row.endswith("identical") for row in rows), result.stdout
