"""BC and IQL: losses against hand-computed values, learning the demos, and runs through the runner."""

import numpy as np
import pytest
import torch

import lava_bridge_mj
from lava_bridge_mj.agents.offline import BC, IQL, BCConfig, IQLConfig, expectile_loss
from lava_bridge_mj.agents.seed_batch import stack_batches
from lava_bridge_mj.eval.training.runner import RunConfig, demo_buffer, train


from conftest import interrupted_copy, metrics_without_wall_time

pytestmark = pytest.mark.usefixtures("one_torch_thread")


def test_expectile_loss_by_hand():
    diff = torch.tensor([2.0, -2.0, 0.5, -0.5])
    # tau = 0.9: positive differences weigh 0.9, negative ones 0.1
    expected = torch.tensor([0.9 * 4.0, 0.1 * 4.0, 0.9 * 0.25, 0.1 * 0.25])
    torch.testing.assert_close(expectile_loss(diff, 0.9), expected)
    torch.testing.assert_close(expectile_loss(diff, 0.5), 0.5 * diff**2)


def test_iql_value_is_an_upper_expectile_of_q():
    """With Q fixed (lr 0 for the critics), V(s) on one state with Q values {0, 1} in the data moves
    to the tau-expectile of {0, 1}, which is tau for two equally likely values."""
    config = IQLConfig(hidden_sizes=(16,), expectile=0.8)
    agent = IQL(1, 1, config, seeds=[0])
    for p in agent.critic_optimizer.param_groups:
        p["lr"] = 0.0
    # make the target critic output exactly the action: Q(s, a) = a for a in {0, 1}
    with torch.no_grad():
        for q in (agent.target_critic.q1, agent.target_critic.q2, agent.critic.q1, agent.critic.q2):
            for layer in q:
                if isinstance(layer, torch.nn.Module) and hasattr(layer, "weight"):
                    layer.weight.zero_()
                    layer.bias.zero_()
            q[0].weight[0, 1, 0] = 1.0  # hidden unit 0 = relu(action)
            q[-1].weight[0, 0, 0] = 1.0
    agent.config.tau = 1e-12  # keep the target critic where it is
    obs = torch.zeros(1, 256, 1)
    action = torch.tensor([0.0, 1.0]).repeat(128).view(1, 256, 1)
    batch = {"obs": obs, "action": action, "reward": torch.zeros(1, 256), "next_obs": obs,
             "terminated": torch.ones(1, 256)}
    for _ in range(1500):
        agent.update(batch)
    assert agent.value(obs[:, :1]).item() == pytest.approx(0.8, abs=0.02)


def test_bc_fits_the_demo_actions():
    demos = lava_bridge_mj.load_demos(500)
    buffer = demo_buffer(RunConfig(method="bc", demos=500))
    agent, rng = BC(4, 2, BCConfig(hidden_sizes=(64, 64)), seeds=[0]), np.random.default_rng(0)
    first = agent.update(stack_batches([buffer.sample(256, rng)]))["actor_loss"][0]
    for _ in range(1500):
        last = agent.update(stack_batches([buffer.sample(256, rng)]))["actor_loss"][0]
    predicted = agent.act(demos["observations"][None].astype(np.float32), deterministic=True)[0]
    error = np.abs(predicted - demos["actions"]).mean()
    assert last < first - 2.0, (first, last)  # the negative log-likelihood fell by far
    assert error < 0.1, f"mean absolute action error {error:.3f} on the demos"


@pytest.mark.parametrize("method", ["bc", "iql"])
def test_offline_runs_never_step_the_env_and_resume_exactly(tmp_path, method):
    section = {"hidden_sizes": [16, 16], "batch_size": 32}
    config = RunConfig(method=method, seed=1, steps=300, eval_every=100, eval_episodes=2, **{method: section})
    full = train(config, tmp_path / "full", progress=False)
    assert all(row["episodes"] == 0 for row in full.rows)
    assert len(full.seed_runs[0].buffer) == 0, "an offline run must not collect online data"
    assert np.isfinite(full.rows[-1]["actor_loss"])

    interrupted_copy(tmp_path / "full", tmp_path / "resumed")
    train(config, tmp_path / "resumed", resume=True, progress=False)
    assert metrics_without_wall_time(tmp_path / "resumed") == metrics_without_wall_time(tmp_path / "full")
