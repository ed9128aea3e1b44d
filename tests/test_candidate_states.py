"""`lava_bridge_mj.candidate_states`: the seeded subset of demo states a run's start strategies start from."""

import json
from pathlib import Path

import numpy as np
import pytest

import lava_bridge_mj
from lava_bridge_mj.eval.training.config import RunConfig
from lava_bridge_mj.eval.training.seed_run import candidate_states as run_candidates

RESULTS = Path(__file__).resolve().parents[1] / "results"
# Runs the trainer wrote before the subset had a public function; their start_weights.npz holds the
# candidate states they trained from: Lava Bridge with both demo sets, and another task of the suite.
COMMITTED_RUNS = ["protocol/auxss-d500/seed3", "protocol/auxss-d7500/seed0", "protocol/omega_ss-d500/seed7",
                  "suite/screening/LavaBridgeTwoCrossings-v0/uniform_ss-d500/seed104"]


@pytest.mark.parametrize("run", COMMITTED_RUNS)
def test_the_subset_is_the_one_committed_runs_trained_from(run):
    config = json.loads((RESULTS / run / "config.json").read_text())
    demos = lava_bridge_mj.load_demos(config["demos"], env_id=config.get("env_id", lava_bridge_mj.ENV_ID))
    states = lava_bridge_mj.candidate_states(demos["observations"], config["demo_subset"], config["seed"])
    assert np.array_equal(states, np.load(RESULTS / run / "start_weights.npz")["states"])


def test_the_trainer_takes_its_candidates_from_it():
    demos = lava_bridge_mj.load_demos(500)["observations"]
    for seed in (0, 5):
        states, episode_ids = run_candidates(RunConfig(method="auxss", seed=seed, demo_subset=40))
        assert episode_ids is None
        assert np.array_equal(states, lava_bridge_mj.candidate_states(demos, n=40, seed=seed))


def test_a_seeded_subset_without_repeats_in_the_demo_sets_order():
    demos = np.arange(1000, dtype=np.float32).reshape(500, 2)
    states = lava_bridge_mj.candidate_states(demos)
    assert states.shape == (150, 2)
    assert np.all(np.diff(states[:, 0]) > 0)  # distinct rows, kept in the demo set's order
    assert np.array_equal(states, lava_bridge_mj.candidate_states(demos, seed=0))
    assert not np.array_equal(states, lava_bridge_mj.candidate_states(demos, seed=1))
    assert np.array_equal(lava_bridge_mj.candidate_states(demos[:20]), demos[:20])  # fewer than n: all


@pytest.mark.parametrize("states, n, match", [(np.zeros((0, 4)), 150, "shape"), (np.zeros(4), 150, "shape"),
                                              (np.zeros((5, 4)), 0, "n=0"), (np.zeros((5, 4)), 2.5, "n=2.5")])
def test_bad_input_is_refused_by_name(states, n, match):
    with pytest.raises(ValueError, match=match):
        lava_bridge_mj.candidate_states(states, n)
