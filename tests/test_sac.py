"""SAC, its networks and its replay buffer: learning on a tiny sparse task, exact targets, exact resume."""

import copy
import dataclasses
import io

import numpy as np
import pytest
import torch

from lava_bridge_mj.agents.networks import MLP, StackedLinear, TanhGaussianActor, TwinQ, init_member, soft_update
from lava_bridge_mj.agents.replay_buffer import ReplayBuffer
from lava_bridge_mj.agents.sac import SAC, SACConfig, alpha_loss_gradient, bellman_target
from lava_bridge_mj.agents.seed_batch import stack_batches

SMALL = SACConfig(hidden_sizes=(64, 64), batch_size=64, learning_starts=400)


pytestmark = pytest.mark.usefixtures("one_torch_thread")  # timings and results as in the experiments


class ReachRight:
    """A 1-D sparse-reward task: x starts at 0, each step x += 0.3 * a for a in [-1, 1] (a wall at
    x = -1); reaching x >= 1 gives +1 and terminates; 20 steps truncate. The observation is
    (x, t / 20). A uniform random policy succeeds about 17% of the time; pushing right always wins."""

    max_steps = 20

    def reset(self):
        self.x, self.t = 0.0, 0
        return self._obs()

    def step(self, action):
        self.x = max(self.x + 0.3 * float(np.clip(action[0], -1.0, 1.0)), -1.0)
        self.t += 1
        terminated = self.x >= 1.0
        return self._obs(), float(terminated), terminated, self.t >= self.max_steps

    def _obs(self):
        return np.array([self.x, self.t / self.max_steps], dtype=np.float32)


def success_rate(policy, episodes):
    env, wins = ReachRight(), 0
    for _ in range(episodes):
        obs, terminated, truncated = env.reset(), False, False
        while not (terminated or truncated):
            obs, _, terminated, truncated = env.step(policy(obs))
        wins += terminated
    return wins / episodes


def train_on_reach_right(seed, steps, config=SMALL):
    """The runner's loop in miniature: random actions, then act / store / one update per step."""
    env, agent = ReachRight(), SAC(2, 1, config, seeds=[seed])
    buffer, rng = ReplayBuffer(config.buffer_size, 2, 1), np.random.default_rng(seed)
    obs = env.reset()
    for step in range(steps):
        if step < config.learning_starts:
            action = rng.uniform(-1.0, 1.0, 1).astype(np.float32)
        else:
            action = agent.act(obs[None])[0]
        next_obs, reward, terminated, truncated = env.step(action)
        buffer.add(obs, action, reward, next_obs, terminated)
        obs = env.reset() if terminated or truncated else next_obs
        if step >= config.learning_starts:
            agent.update(stack_batches([buffer.sample(config.batch_size, rng)]))
    return agent


def filled_buffer(n=500, seed=0):
    rng, buffer = np.random.default_rng(seed), ReplayBuffer(1_000, 4, 2)
    for _ in range(n):
        buffer.add(rng.normal(size=4), rng.uniform(-1, 1, 2), float(rng.random() < 0.1),
                   rng.normal(size=4), rng.random() < 0.1)
    return buffer


def parameters(agent, i=0):
    """Seed i's parameters, flattened into one vector."""
    return torch.cat([p.detach()[i].flatten() for net in (agent.actor, agent.critic, agent.target_critic)
                      for p in net.parameters()] + [agent.log_alpha.detach()[i].view(1)])


def policy(agent, deterministic=False):
    """A single-seed agent as a map from one observation (or a batch of them) to actions."""
    return lambda obs: agent.act(np.asarray(obs, dtype=np.float32)[None], deterministic=deterministic)[0]


# --- learning -------------------------------------------------------------------------------------

def test_sac_solves_a_tiny_sparse_task_that_random_actions_rarely_solve():
    rng = np.random.default_rng(0)
    random_rate = success_rate(lambda obs: rng.uniform(-1.0, 1.0, 1), 1_000)
    agent = train_on_reach_right(seed=0, steps=1_500)
    assert random_rate < 0.3
    assert success_rate(policy(agent, deterministic=True), 1) == 1.0  # the env is deterministic
    assert success_rate(policy(agent), 100) >= 0.9


def test_update_returns_finite_per_seed_metrics():
    agent, buffer, rng = SAC(4, 2, SMALL, seeds=[0, 1, 2]), filled_buffer(), np.random.default_rng(0)
    metrics = agent.update(stack_batches([buffer.sample(64, rng) for _ in range(3)]))
    assert set(metrics) == {"critic_loss", "actor_loss", "alpha", "q_mean", "entropy"}
    assert all(v.shape == (3,) and np.isfinite(v).all() for v in metrics.values())
    np.testing.assert_allclose(metrics["alpha"], SMALL.initial_alpha, rtol=1e-6)
    assert len(set(metrics["critic_loss"].tolist())) == 3, "seeds saw different data and weights"


# --- the Bellman target: termination cuts the future, truncation bootstraps --------------------------

def test_bellman_target_by_hand():
    reward = torch.tensor([1.0, 1.0, -1.0, 0.0])
    terminated = torch.tensor([0.0, 1.0, 1.0, 0.0])
    next_value = torch.tensor([2.0, 2.0, 5.0, -3.0])
    expected = torch.tensor([1.0 + 0.9 * 2.0, 1.0, -1.0, 0.9 * -3.0])
    torch.testing.assert_close(bellman_target(reward, terminated, next_value, gamma=0.9), expected)


def test_sac_td_target_bootstraps_truncated_but_not_terminated_transitions():
    agent = SAC(4, 2, SACConfig(hidden_sizes=(16, 16), gamma=0.9, initial_alpha=0.5), seeds=[3])
    # Two copies of one transition: the first truncated (terminated = 0), the second terminated.
    batch = {"obs": torch.ones(1, 2, 4), "action": torch.zeros(1, 2, 2), "reward": torch.tensor([[0.5, 0.5]]),
             "next_obs": torch.full((1, 2, 4), 0.3), "terminated": torch.tensor([[0.0, 1.0]])}
    noise_state = agent.generators[0].get_state()
    target = agent.td_target(batch)[0]

    agent.generators[0].set_state(noise_state)  # redraw the same next actions by hand
    with torch.no_grad():
        next_action, next_log_prob = agent.actor(batch["next_obs"], generators=agent.generators)
        q1, q2 = agent.target_critic.both(batch["next_obs"], next_action)
        soft_value = (torch.minimum(q1, q2) - 0.5 * next_log_prob)[0]
    torch.testing.assert_close(target[0], 0.5 + 0.9 * soft_value[0])
    torch.testing.assert_close(target[1], torch.tensor(0.5))
    assert abs(soft_value[0].item()) > 1e-3  # otherwise the first check could not tell the two apart


# --- the entropy target: which way alpha moves ------------------------------------------------------

@pytest.mark.parametrize("target_entropy", [50.0, -50.0, None])
def test_target_entropy_decides_which_way_alpha_moves(target_entropy):
    # The gradient of the alpha loss -log_alpha * (log pi + target) is entropy - target, and Adam's first
    # step is lr * g / (|g| + eps): log alpha moves by lr, up while the entropy is below the target and
    # down while above it. None is -act_dim = -2.
    agent = SAC(4, 2, dataclasses.replace(SMALL, target_entropy=target_entropy), seeds=[0])
    assert agent.target_entropy == (-2.0 if target_entropy is None else target_entropy)
    before = agent.log_alpha.item()
    entropy = agent.update(stack_batches([filled_buffer().sample(64, np.random.default_rng(0))]))["entropy"][0]
    assert -10 < entropy < 10  # a fresh tanh-Gaussian policy: far from +-50
    expected_move = SMALL.lr * float(np.sign(agent.target_entropy - entropy))
    assert agent.log_alpha.item() - before == pytest.approx(expected_move, abs=1e-6)


@pytest.mark.parametrize("seeds, batch_size", [(1, 256), (2, 32), (3, 100), (5, 7)])
def test_alpha_loss_gradient_is_autograds_bit_for_bit(seeds, batch_size):
    # the update writes the alpha loss's gradient out; it must be the very numbers backward() gives,
    # batch sizes that are not powers of two (where -1/B rounds) included
    generator = torch.Generator().manual_seed(seeds * batch_size)
    log_alpha = torch.randn(seeds, generator=generator).requires_grad_(True)
    log_prob = torch.randn(seeds, batch_size, generator=generator) * 10 ** torch.empty(seeds, batch_size).uniform_(
        -3, 2, generator=generator)
    (-(log_alpha.unsqueeze(1) * (log_prob + -2.0)).mean(1)).sum().backward()
    written = alpha_loss_gradient(log_prob, -2.0)
    assert written.shape == (seeds,) and torch.equal(written, log_alpha.grad)
    torch.testing.assert_close(written, -(log_prob - 2.0).mean(1))  # and it is the gradient


# --- networks --------------------------------------------------------------------------------------

def test_mlp_and_twin_q_shapes():
    net = MLP(2, 3, 5, (7, 11))
    assert [tuple(m.weight.shape) for m in net if isinstance(m, StackedLinear)] == [(2, 3, 7), (2, 7, 11), (2, 11, 5)]
    q = TwinQ(2, 4, 2, (8,))
    for module in (net, q):
        for p in module.parameters():
            torch.nn.init.uniform_(p, -1, 1)
    q1, q2 = q.both(torch.randn(2, 6, 4), torch.randn(2, 6, 2))
    assert q1.shape == q2.shape == (2, 6) and not torch.equal(q1, q2)
    assert q(torch.randn(2, 6, 4), torch.randn(2, 6, 2)).shape == (2, 6)


def test_stacked_linear_is_one_linear_layer_per_member():
    layer = StackedLinear(3, 4, 5)
    for i in range(3):
        layer.init_member(i, torch.Generator().manual_seed(i))
    x = torch.randn(3, 7, 4)
    for i in range(3):
        torch.testing.assert_close(layer(x)[i], x[i] @ layer.weight[i] + layer.bias[i])
    assert not torch.equal(layer.weight[0], layer.weight[1])
    bound = 1 / 2  # nn.Linear's U(-1/sqrt(in), 1/sqrt(in)) with in = 4
    assert layer.weight.abs().max() <= bound and layer.bias.abs().max() <= bound


def test_tanh_gaussian_log_prob_matches_torch_distributions():
    torch.manual_seed(0)
    actor = TanhGaussianActor(1, 4, 3, (32,))
    for p in actor.parameters():
        torch.nn.init.uniform_(p, -0.3, 0.3)
    obs = torch.randn(1, 500, 4)
    action, log_prob = actor(obs, generators=[torch.Generator().manual_seed(0)])
    mean, log_std = actor.distribution(obs)
    reference = torch.distributions.TransformedDistribution(
        torch.distributions.Independent(torch.distributions.Normal(mean, log_std.exp()), 1),
        [torch.distributions.TanhTransform()])
    inside = action.abs().max(-1).values < 0.99  # the reference's atanh is unstable at the bound
    assert inside.sum() > 400
    torch.testing.assert_close(log_prob[inside], reference.log_prob(action)[inside], rtol=1e-4, atol=1e-4)
    torch.testing.assert_close(actor.log_prob(obs, action)[inside], log_prob[inside], rtol=1e-3, atol=1e-3)
    assert action.abs().max() <= 1.0 and torch.isfinite(log_prob).all()


def test_deterministic_action_is_tanh_of_mean():
    actor = TanhGaussianActor(2, 4, 2)
    for p in actor.parameters():
        torch.nn.init.uniform_(p, -0.3, 0.3)
    obs = torch.randn(2, 3, 4)
    action, _ = actor(obs, deterministic=True)
    torch.testing.assert_close(action, torch.tanh(actor.distribution(obs)[0]))


def test_soft_update_interpolates():
    source, target = torch.nn.Linear(3, 2), torch.nn.Linear(3, 2)
    before = copy.deepcopy(target)
    soft_update(target.parameters(), source.parameters(), tau=0.25)
    torch.testing.assert_close(target.weight, 0.75 * before.weight + 0.25 * source.weight)
    torch.testing.assert_close(target.bias, 0.75 * before.bias + 0.25 * source.bias)
    soft_update(target.parameters(), source.parameters(), tau=1.0)
    torch.testing.assert_close(target.bias, source.bias)


def test_critic_layer_norm_normalises_each_members_hidden_units():
    """With critic_layer_norm every hidden layer's pre-activations have mean 0 and variance 1 per
    sample (the affine part starts at identity), member by member; without it they do not."""
    captured = []
    for layer_norm in (False, True):
        q = TwinQ(3, 4, 2, (16, 16), layer_norm=layer_norm)
        for i in range(3):
            init_member(q, i, torch.Generator().manual_seed(i))
        relus = [m for m in q.q1 if isinstance(m, torch.nn.ReLU)]
        inputs = []
        # a copy before the ReLU runs: it works in place
        hooks = [r.register_forward_pre_hook(lambda m, args: inputs.append(args[0].clone())) for r in relus]
        q(torch.randn(3, 50, 4) * 5, torch.rand(3, 50, 2))
        for h in hooks:
            h.remove()
        captured.append(inputs)
    for hidden in captured[1]:
        torch.testing.assert_close(hidden.mean(-1), torch.zeros(3, 50), atol=1e-5, rtol=0)
        torch.testing.assert_close(hidden.var(-1, unbiased=False), torch.ones(3, 50), atol=1e-3, rtol=0)
    assert not torch.allclose(captured[0][0].mean(-1), torch.zeros(3, 50), atol=1e-2)
    with pytest.raises(ValueError, match="critic_layer_norm must be true or false, got 'yes'"):
        SACConfig(critic_layer_norm="yes")


# --- replay buffer ---------------------------------------------------------------------------------

def test_replay_buffer_overwrites_oldest_when_full():
    buffer = ReplayBuffer(3, obs_dim=1, act_dim=1)
    for i in range(5):
        buffer.add([i], [0.1 * i], float(i), [i + 1], terminated=(i == 4))
    assert len(buffer) == 3
    assert buffer.obs[:, 0].tolist() == [3.0, 4.0, 2.0]  # 0 and 1 were overwritten in place
    batch = buffer.sample(200, np.random.default_rng(0))
    assert set(batch["obs"][:, 0].tolist()) == {2.0, 3.0, 4.0}
    torch.testing.assert_close(batch["next_obs"], batch["obs"] + 1)
    torch.testing.assert_close(batch["reward"], batch["obs"][:, 0])
    torch.testing.assert_close(batch["terminated"], (batch["obs"][:, 0] == 4).float())
    assert all(t.dtype == torch.float32 for t in batch.values())
    assert batch["action"].shape == (200, 1) and batch["reward"].shape == (200,)


def test_replay_buffer_state_dict_round_trip():
    buffer = filled_buffer(n=1_234)  # wrapped around: pos != size
    restored = ReplayBuffer(1_000, 4, 2)
    restored.load_state_dict(buffer.state_dict())
    assert (len(restored), restored.pos) == (len(buffer), buffer.pos) == (1_000, 234)
    for name, value in buffer.sample(64, np.random.default_rng(7)).items():
        torch.testing.assert_close(restored.sample(64, np.random.default_rng(7))[name], value)
    for b in (buffer, restored):
        b.add(np.ones(4), np.ones(2), 1.0, np.ones(4), True)
    assert np.array_equal(buffer.obs, restored.obs) and buffer.pos == restored.pos == 235


def test_replay_buffer_sampling_is_seeded():
    buffer = filled_buffer()
    a, b = (buffer.sample(32, np.random.default_rng(1)) for _ in range(2))
    assert all(torch.equal(a[k], b[k]) for k in a)
    with pytest.raises(ValueError):
        ReplayBuffer(10, 4, 2).sample(1, np.random.default_rng(0))


# --- reproducibility and exact resume --------------------------------------------------------------

def run_updates(seeds, n, buffer, config=SMALL):
    """n updates of a batch of seeds, seed s sampling its minibatches with default_rng(s)."""
    agent, rngs = SAC(4, 2, config, seeds=seeds), [np.random.default_rng(s) for s in seeds]
    for _ in range(n):
        agent.update(stack_batches([buffer.sample(64, rng) for rng in rngs]))
    return agent


def test_same_seed_gives_identical_parameters_whatever_the_global_rng():
    buffer = filled_buffer()
    torch.manual_seed(123)
    first = run_updates([0], 20, buffer)
    torch.rand(1000)  # disturb torch's global RNG: the agent must not depend on it
    second = run_updates([0], 20, buffer)
    other = run_updates([1], 20, buffer)
    assert torch.equal(parameters(first), parameters(second))
    assert not torch.equal(parameters(first), parameters(other))


@pytest.mark.parametrize("layer_norm", [False, True])
def test_a_seed_is_bit_identical_alone_and_inside_a_batch(layer_norm):
    """Seed 3 trained alone and as the second of four seeds: same weights, actions and statistics."""
    buffer = filled_buffer()
    config = dataclasses.replace(SMALL, critic_layer_norm=layer_norm)
    alone, batched = run_updates([3], 15, buffer, config), run_updates([0, 3, 5, 8], 15, buffer, config)
    assert torch.equal(parameters(alone), parameters(batched, 1))
    assert not torch.equal(parameters(batched, 0), parameters(batched, 1))
    obs = np.random.default_rng(1).normal(size=(4, 6, 4)).astype(np.float32)
    np.testing.assert_array_equal(alone.act(obs[1:2])[0], batched.act(obs)[1])  # noise from seed 3's generator
    stats_alone = alone.update(stack_batches([buffer.sample(64, np.random.default_rng(9))]))
    stats_batched = batched.update(stack_batches([buffer.sample(64, np.random.default_rng(s)) for s in (5, 9, 6, 7)]))
    for name, values in stats_alone.items():
        assert values[0] == stats_batched[name][1], name


def test_seed_states_round_trip_into_another_batch():
    """Checkpoints are per seed: seeds 0 and 5 of one batch continue exactly as seeds of a new batch."""
    buffer = filled_buffer()
    agent = run_updates([0, 2, 5], 10, buffer)
    saved = io.BytesIO()
    torch.save([agent.seed_state(0), agent.seed_state(2)], saved)
    saved.seek(0)
    restored = SAC(4, 2, SMALL, seeds=[0, 5])
    restored.load_seed_states(torch.load(saved))
    assert torch.equal(parameters(restored, 0), parameters(agent, 0))
    assert torch.equal(parameters(restored, 1), parameters(agent, 2))

    obs = np.random.default_rng(1).normal(size=(3, 5, 4)).astype(np.float32)
    np.testing.assert_array_equal(restored.act(obs[[0, 2]], deterministic=True), agent.act(obs, deterministic=True)[[0, 2]])
    np.testing.assert_array_equal(restored.act(obs[[0, 2]]), agent.act(obs)[[0, 2]])  # generators restored
    batch = stack_batches([buffer.sample(64, np.random.default_rng(i)) for i in range(3)])
    restored.update({name: value[[0, 2]] for name, value in batch.items()})
    agent.update(batch)
    assert torch.equal(parameters(restored, 1), parameters(agent, 2))
    exp_avg = restored.actor_optimizer.state_dict()["state"][0]["exp_avg"]
    assert torch.equal(exp_avg, agent.actor_optimizer.state_dict()["state"][0]["exp_avg"][[0, 2]])


def test_a_seed_state_does_not_change_when_training_goes_on():
    """Adam counts its steps in place in tensors shared by all seeds: a seed state holds a copy."""
    buffer = filled_buffer()
    agent = run_updates([0], 2, buffer)
    state = agent.seed_state(0)
    agent.update(stack_batches([buffer.sample(64, np.random.default_rng(0))]))
    assert all(moments["step"].item() == 2 for moments in state["critic_optimizer"]["state"].values())


def test_seed_states_of_different_steps_or_seeds_are_refused():
    buffer = filled_buffer()
    early, late = run_updates([0], 2, buffer), run_updates([1], 3, buffer)
    with pytest.raises(ValueError, match="same step"):
        SAC(4, 2, SMALL, seeds=[0, 1]).load_seed_states([early.seed_state(0), late.seed_state(0)])
    with pytest.raises(ValueError, match=r"cannot load into seeds \[4\]"):
        SAC(4, 2, SMALL, seeds=[4]).load_seed_states([early.seed_state(0)])
