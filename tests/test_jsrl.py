"""JSRL: the curriculum's horizons and advancement, the hand-over at step h, and a resumable run."""

import numpy as np
import pytest
from conftest import interrupted_copy, metrics_without_wall_time

from lava_bridge_mj.agents.jsrl import JSRLConfig, JSRLCurriculum
from lava_bridge_mj.eval.training.runner import Run, RunConfig, train


def test_curriculum_horizons_and_advancement_by_hand():
    curriculum = JSRLCurriculum(JSRLConfig(initial_horizon=100, stages=4, window=4, threshold=0.5))
    assert curriculum.horizon == 100
    for success in (True, False, False):  # 3 episodes: the window is not full yet
        curriculum.record(success)
    assert curriculum.stage == 0
    curriculum.record(False)  # 1 of 4 < 0.5
    assert curriculum.stage == 0
    curriculum.record(True)  # last 4: F, F, F, T -> 0.25
    curriculum.record(True)  # F, F, T, T -> 0.5: advance
    assert (curriculum.stage, curriculum.horizon, curriculum.results) == (1, 75, [])
    for _ in range(3 * 4):
        curriculum.record(True)
    assert (curriculum.stage, curriculum.horizon) == (4, 0)
    for _ in range(8):
        curriculum.record(True)
    assert curriculum.stage == 4, "the last stage is the learner alone; it does not advance further"


def test_curriculum_state_round_trips():
    a = JSRLCurriculum(JSRLConfig(window=3))
    for success in (True, False, True, True, True):
        a.record(success)
    b = JSRLCurriculum(JSRLConfig(window=3))
    b.load_state_dict(a.state_dict())
    assert (b.stage, b.results) == (a.stage, a.results)


@pytest.mark.parametrize("bad, message", [({"guide": "ppo"}, "guide must be 'iql' or 'bc'"),
                                          ({"stages": 0}, "stages must be an integer >= 1"),
                                          ({"threshold": 1.5}, r"threshold must be a number in \[0, 1\]")])
def test_bad_jsrl_settings_are_refused(bad, message):
    with pytest.raises(ValueError, match=message):
        JSRLConfig(**bad)


TINY = dict(method="jsrl", seed=2, steps=400, eval_every=100, eval_episodes=2,
            sac={"hidden_sizes": [16, 16], "batch_size": 32, "buffer_size": 500, "learning_starts": 100},
            bc={"hidden_sizes": [16, 16], "batch_size": 32},
            jsrl={"guide": "bc", "guide_steps": 50, "initial_horizon": 30, "stages": 3, "window": 1, "threshold": 0.0})


def test_the_guide_acts_for_exactly_h_steps_then_the_learner(tmp_path, monkeypatch):
    run = Run([RunConfig(**TINY)], [tmp_path])
    seed_run = run.seed_runs[0]
    run.guide.curricula[0].stage = 1  # h = 20
    # each policy answers with its own constant action, so the actions taken show who acted
    monkeypatch.setattr(run.guide.learner, "act", lambda obs, deterministic=False: np.full((*obs.shape[:-1], 2), 0.5))
    monkeypatch.setattr(run.agent, "act", lambda obs, deterministic=False: np.full((*obs.shape[:-1], 2), -0.25))
    run.guide.trained = True
    taken = []
    original_observe = seed_run.observe
    monkeypatch.setattr(seed_run, "observe", lambda step, action, *rest: (taken.append(np.array(action)),
                                                                          original_observe(step, action, *rest))[1])
    monkeypatch.setattr(run.config.sac, "learning_starts", 0)
    run.config.steps = 25
    run._train(progress=False)
    taken = np.array(taken)
    first_episode = taken[: min(25, len(taken))]
    assert np.all(first_episode[:20] == 0.5), "the guide acts for the first h = 20 steps"
    assert np.all(first_episode[20:25] == -0.25), "then the learner"


def test_a_jsrl_run_advances_its_horizon_and_resumes_exactly(tmp_path):
    config = RunConfig(**TINY)
    train(config, tmp_path / "full", progress=False)
    rows = metrics_without_wall_time(tmp_path / "full")
    horizons = [float(r["guide_horizon"]) for r in rows]
    assert horizons[0] <= 30 and horizons[-1] < 30 and horizons == sorted(horizons, reverse=True), horizons

    interrupted_copy(tmp_path / "full", tmp_path / "resumed")
    train(config, tmp_path / "resumed", resume=True, progress=False)
    assert metrics_without_wall_time(tmp_path / "resumed") == metrics_without_wall_time(tmp_path / "full")
