"""RFCL as published (agents/rfcl.py): `rfcl_reverse`'s weights, pointer moves, time limits and hand-over,
and `rfcl`'s forward curriculum over seeded p0 states, against hand-computed values; a resume of both;
both trained through the CLI; the study's second question reading AuxSS against rfcl where it was run."""

import csv
import json
from pathlib import Path

import gymnasium
import numpy as np
import pytest

import lava_bridge_mj
from conftest import (episode_rows, groups_in, held_back_tasks, makefile_commands, makefile_sweeps, study_report_command,
                      write_metric_runs)
from test_runner import resume_from_mid_episode_checkpoint, tiny_config

from lava_bridge_mj.agents import NO_STATE, RFCLReverseSS, RFCLSS, StartStateWrapper, StrategyContext
from lava_bridge_mj.agents.reverse_curriculum import goal_reaching_demos
from lava_bridge_mj.agents.strategy_registry import make_start_strategy
from lava_bridge_mj.eval import cli
from lava_bridge_mj.eval.training.runner import train


def two_demos():
    """Demo 0 of 10 states, demo 1 of 6, in 2-D (the states' values matter to nothing here)."""
    states = np.arange(32, dtype=np.float64).reshape(16, 2)
    return states, np.repeat([0, 1], [10, 6])


def succeed(strategy, index, times=3):
    for _ in range(times):
        strategy.update(index, 5, success=True)


# --- the reverse stage ---------------------------------------------------------------------------
def test_demos_are_weighted_by_their_remaining_fraction_and_starts_spread_geometrically():
    rc = RFCLReverseSS(*two_demos())
    # t = (9, 5): every offset of the spread is past the last state, so each demo's weight t_i / T_i sits there
    np.testing.assert_array_equal(rc.start_steps, [9, 5])
    expected = np.zeros(16)
    expected[9], expected[15] = 9 / 10, 5 / 6
    np.testing.assert_allclose(rc.weights, expected, rtol=1e-15)
    succeed(rc, 9)  # three successes from t_0 = 9 move it back 4 states, to 5
    np.testing.assert_array_equal(rc.start_steps, [5, 5])
    expected[9] = 0.0
    expected[5:10] = 5 / 10 * np.array([1 / 2, 1 / 4, 1 / 8, 1 / 16, 1 / 16])  # states 5..9 of demo 0
    np.testing.assert_allclose(rc.weights, expected, rtol=1e-15)
    np.testing.assert_allclose(rc.probabilities, expected / (0.5 + 5 / 6), rtol=1e-14)


def test_only_episodes_from_the_pointer_itself_move_it_and_it_stops_at_zero():
    rc = RFCLReverseSS(*two_demos())
    succeed(rc, 9)
    succeed(rc, 6)  # a spread start, one state after t_0 = 5: says nothing about t_0
    assert rc.start_steps.tolist() == [5, 5]
    for success in (True, False, True, True):  # the buffer holds the last 3: [F, T, T] is not all
        rc.update(5, 3, success=success)
    assert rc.start_steps.tolist() == [5, 5]
    rc.update(5, 3, success=True)  # [T, T, T]
    assert rc.start_steps.tolist() == [1, 5]
    succeed(rc, 1)  # max(1 - 4, 0)
    assert rc.start_steps.tolist() == [0, 5]
    # at t_i = 0 a demonstration keeps RFCL's 1e-6, spread over its first 5 states
    np.testing.assert_allclose(rc.weights[:5], 1e-6 * np.array([1 / 2, 1 / 4, 1 / 8, 1 / 16, 1 / 16]), rtol=1e-15)
    succeed(rc, 0)
    assert rc.solved.tolist() == [True, False]


def test_the_time_limit_is_16_plus_a_third_of_the_demonstration_steps_left():
    rc = RFCLReverseSS(*two_demos())
    # demo 0's state 0 is 10 steps from the goal: 16 + 10 // 3; its last state 1 step: 16 + 0
    assert [rc.time_limit(i) for i in (0, 1, 9, 10, 15)] == [19, 19, 16, 18, 16]
    assert RFCLReverseSS(*two_demos(), demo_horizon_to_max_steps_ratio=None).time_limit(0) is None


def test_fixed_point_starts_put_each_demos_weight_on_its_pointer():
    rc = RFCLReverseSS(*two_demos(), start_step_sampler="fixed_point")
    succeed(rc, 9)
    assert np.flatnonzero(rc.weights).tolist() == [5, 15]
    np.testing.assert_allclose(rc.weights[[5, 15]], [0.5, 5 / 6], rtol=1e-15)


def one_state_demos(k):
    """k demonstrations of one state each: t_i = 0 from the start, so 3 successes solve one."""
    return np.arange(2 * k, dtype=np.float64).reshape(k, 2), np.arange(k)


def test_the_reverse_stage_hands_over_once_more_than_90_percent_are_solved():
    rc = RFCLReverseSS(*one_state_demos(11))
    for demo in range(9):
        succeed(rc, demo)
    assert rc.phase == "reverse" and rc.solved_fraction == pytest.approx(9 / 11)
    succeed(rc, 9)  # 10 of 11 = 0.909 > 0.9, one still unsolved
    assert rc.phase == "p0" and not rc.solved.all()
    assert rc.sample(np.random.default_rng(0)) == NO_STATE
    assert rc.time_limit(10) is not None  # a demo state keeps its limit, but is no longer drawn
    succeed(rc, 10)  # an episode from a demo state started before the hand-over changes nothing
    assert rc.solved.tolist() == [True] * 10 + [False]
    # exactly 0.9 is not more: 9 of 10
    rc = RFCLReverseSS(*one_state_demos(10))
    for demo in range(9):
        succeed(rc, demo)
    assert rc.phase == "reverse"


def test_bad_settings_are_refused_by_name():
    with pytest.raises(ValueError, match=r"start_step_sampler must be one of \('geometric', 'fixed_point'\), got 'x'"):
        RFCLReverseSS(*two_demos(), start_step_sampler="x")
    with pytest.raises(ValueError, match=r"handover_solved_fraction must be a number in \[0, 1\), got 1"):
        RFCLReverseSS(*two_demos(), handover_solved_fraction=1)
    with pytest.raises(ValueError, match=r"forward_seeds must be an integer >= 1, got 0"):
        RFCLSS(*two_demos(), forward_seeds=0)


# --- the forward stage ---------------------------------------------------------------------------
def forward_rfcl(k=3):
    """`rfcl` with one demonstration of one state and k forward states, its demonstration solved."""
    states, ids = one_state_demos(1)
    rfcl = RFCLSS(states, ids, forward_states=np.arange(2 * k, dtype=np.float64).reshape(k, 2) + 100)
    assert rfcl.phase == "reverse"
    succeed(rfcl, 0)
    assert rfcl.phase == "forward"
    return rfcl


def test_forward_probabilities_follow_rfcls_scores_ranks_and_staleness():
    rfcl = forward_rfcl()
    # nothing tried yet: every score 2, every staleness 0, so all tie
    np.testing.assert_allclose(rfcl.probabilities, [0, 1 / 3, 1 / 3, 1 / 3], rtol=1e-14)
    rfcl.update(1, 20, success=True)  # state A: 1 of its last 5 -> 0.2 -> score 3 (the frontier)
    for _ in range(5):
        rfcl.update(2, 20, success=True)  # state B: 5 of 5 -> score 1
    # state C: never tried -> score 2. Scores (3, 1, 2); a value with c values at or above it has rank
    # c + 1: ranks (2, 4, 3), weights rank ** -10. Staleness all 0: ranks (4, 4, 4), equal.
    score = np.array([2.0**-10, 4.0**-10, 3.0**-10])
    expected = 0.9 * score / score.sum() + 0.1 / 3
    np.testing.assert_allclose(rfcl.probabilities[1:], expected, rtol=1e-12)
    assert rfcl.time_limit(1) is None  # the env's own limit
    # each draw makes every other state one draw staler
    rng = np.random.default_rng(5)
    drawn = [rfcl.sample(rng) for _ in range(3)]
    staleness = np.zeros(3)
    for index in drawn:
        staleness += 1
        staleness[index - 1] = 0
    assert rfcl.state_dict()["staleness"] == staleness.astype(int).tolist()


def test_forward_probabilities_with_known_staleness():
    rfcl = forward_rfcl()
    state = rfcl.state_dict()
    state["forward_outcomes"] = [[True], [True] * 5, []]
    state["staleness"] = [0, 2, 5]
    rfcl.load_state_dict(state)
    score = np.array([2.0**-10, 4.0**-10, 3.0**-10])  # scores (3, 1, 2)
    stale = np.array([4.0**-10, 3.0**-10, 2.0**-10])  # staleness (0, 2, 5): ranks (4, 3, 2)
    np.testing.assert_allclose(rfcl.probabilities[1:], 0.9 * score / score.sum() + 0.1 * stale / stale.sum(),
                               rtol=1e-12)


def test_the_learned_state_round_trips_in_either_stage():
    states, ids = two_demos()
    forward = np.arange(8, dtype=np.float64).reshape(4, 2) + 50
    rfcl = RFCLSS(states, ids, forward_states=forward, handover_solved_fraction=0.0)
    succeed(rfcl, 9)
    rng = np.random.default_rng(0)
    for _ in range(3):
        succeed(rfcl, rfcl.start_steps[0])
    assert rfcl.phase == "forward"
    for _ in range(7):
        index = rfcl.sample(rng)
        rfcl.update(index, 9, success=bool(index % 2))
    restored = RFCLSS(states, ids, forward_states=forward, handover_solved_fraction=0.0)
    restored.load_state_dict(json.loads(json.dumps(rfcl.state_dict())))
    assert restored.state_dict() == rfcl.state_dict() and restored.phase == "forward"
    np.testing.assert_array_equal(restored.weights, rfcl.weights)
    a, b = np.random.default_rng(9), np.random.default_rng(9)
    assert [restored.sample(a) for _ in range(6)] == [rfcl.sample(b) for _ in range(6)]
    with pytest.raises(ValueError, match="state_dict is for strategy 'rfcl', not 'rfcl_reverse'"):
        RFCLReverseSS(states, ids).load_state_dict(rfcl.state_dict())


# --- on a task --------------------------------------------------------------------------------
def test_the_run_supplies_the_tasks_own_p0_states_of_seeds_0_to_k():
    env = gymnasium.make("LavaBridge-v0")
    states, ids = goal_reaching_demos(lava_bridge_mj.load_demos(500))
    context = StrategyContext.from_env(env.unwrapped, seed=0, horizon=500, episode_ids=ids)
    rfcl = make_start_strategy("rfcl", states, context, forward_seeds=6, handover_solved_fraction=0.0)
    expected = np.array([lava_bridge_mj.LavaBridgeEnv().reset(seed=s)[0] for s in range(6)])
    np.testing.assert_array_equal(rfcl.forward_states, expected)
    assert len(np.unique(expected, axis=0)) == 6  # p0 is a distribution: six seeds, six states
    assert rfcl.settings["forward_seeds"] == 6 and "forward_states" not in rfcl.settings
    # solve one demonstration (handover at the first): episodes then start exactly at those p0 states
    state = rfcl.state_dict()
    state["start_steps"] = [0] * rfcl.num_demos
    state["solved"] = [True] + [False] * (rfcl.num_demos - 1)
    rfcl.load_state_dict(state)
    wrapped = StartStateWrapper(env, rfcl, seed=0)
    for _ in range(4):
        obs, info = wrapped.reset()
        assert info["start_index"] >= len(states) and wrapped.time_limit is None
        np.testing.assert_array_equal(obs, rfcl.states[info["start_index"]])
    assert make_start_strategy("rfcl_reverse", states, context).phase == "reverse"


@pytest.fixture(scope="module")
def rfcl_run(tmp_path_factory):
    config = tiny_config("rfcl", strategy={"forward_seeds": 20})
    out = tmp_path_factory.mktemp("rfcl") / "run"
    return config, out, train(config, out, progress=False)


def test_an_rfcl_run_moves_its_pointers_and_resumes_exactly(rfcl_run, tmp_path):
    config, full_dir, full = rfcl_run
    assert (full.strategy.start_steps < full.strategy.demo_lengths - 1).any(), "the curriculum never moved back"
    log = episode_rows(full_dir)
    index, length = (np.array([int(r[k]) for r in log]) for k in ("start_index", "length"))
    limits = np.array([full.strategy.time_limit(i) for i in index])
    assert (length <= limits).all() and (length == limits).any()
    weights = np.load(full_dir / "start_weights.npz")  # the 20 p0 states recorded after the demo states
    np.testing.assert_array_equal(weights["states"], full.strategy.states)
    assert weights["probabilities"].shape[1] == len(full.strategy.states) == len(full.strategy.demo_states) + 20
    resumed = resume_from_mid_episode_checkpoint(config, full_dir, full, tmp_path / "resumed")
    assert resumed.strategy.state_dict() == full.strategy.state_dict()


@pytest.mark.parametrize("method", ["rfcl", "rfcl_reverse"])
def test_both_train_two_seeds_through_the_cli(method, tmp_path):
    out = tmp_path / method
    assert cli.main(["train", "--method", method, "--seeds", "0-1", "--steps", "300", "--eval-every", "150",
                     "--eval-episodes", "2", "--set", "sac.hidden_sizes=[16, 16]", "--set", "sac.batch_size=32",
                     "--set", "sac.learning_starts=100", "--threads", "1", "--out", str(out), "--no-progress"]) == 0
    for seed in (0, 1):
        session, = json.loads((out / f"seed{seed}" / "provenance.json").read_text())
        assert session["strategy"]["reverse_step_size"] == 4 and session["strategy"]["max_steps_min"] == 16
        with open(out / f"seed{seed}" / "metrics.csv") as f:
            assert [int(float(r["step"])) for r in csv.DictReader(f)] == [150, 300]


# --- the study's second question ------------------------------------------------------------------
ROOT = Path(__file__).resolve().parent.parent


def reverse_question(groups):
    from lava_bridge_mj.eval.analysis import study

    return next(q for q in study.answer_questions(groups) if q.short == "AuxSS against RFCL")


def test_committed_study_reads_rfcl_exactly_on_the_tasks_that_have_its_runs():
    pytest.importorskip("rliable")
    from lava_bridge_mj.eval.analysis.aggregate import find_runs, group_runs
    from lava_bridge_mj.eval.analysis.report import task_seed_list
    from lava_bridge_mj.eval.analysis.study import answer_questions, answers_record

    report = study_report_command()
    first, last = map(int, report[report.index("--seeds") + 1].split("-"))
    looks = tuple(map(int, report[report.index("--looks") + 1].split(",")))
    # a task whose seed extension is still training is read at the seeds --task-seeds gives it, as the report does
    task_seeds = dict(task_seed_list(f"{task}={seeds}") for task, seeds in held_back_tasks().items())
    groups = group_runs(find_runs(ROOT / report[0], seeds=range(first, last + 1), task_seeds=task_seeds))
    answers = {task: answer_questions([g for g in groups if g.task == task], looks)
               for task in dict.fromkeys(g.task for g in groups)}
    record = json.loads(json.dumps(answers_record(answers, groups)))
    assert record == json.loads((ROOT / "docs/report_study/answers.json").read_text())
    assert {g.task for g in groups if g.method == "rfcl"}
    for task, answer in record.items():
        # rfcl where the task has its runs, else reverse_ss; a task with neither is not asked the question yet
        methods = {g.method for g in groups if g.task == task}
        read = {(c["a"], c["b"]) for c in answer["comparisons"] if c["question"] == 2}
        against = next((m for m in ("rfcl", "reverse_ss") if m in methods), None)
        assert read == ({("auxss", against)} if against else set()), task


def test_with_rfcl_runs_the_second_question_reads_auxss_against_rfcl(tmp_path):
    pytest.importorskip("rliable")
    solved, failed = ({seed: [0.0, p] for seed in range(10)} for p in (1.0, 0.0))
    for method, runs in {"auxss": solved, "reverse_ss": failed}.items():
        write_metric_runs(tmp_path, method, runs)
    without = reverse_question(groups_in(tmp_path))
    assert {(a.a, a.b) for a in without.answers} == {("auxss", "reverse_ss")}
    assert {a.verdict for a in without.answers} == {"auxss ahead"}
    write_metric_runs(tmp_path, "rfcl", solved)  # RFCL as published, as good as AuxSS
    with_rfcl = reverse_question(groups_in(tmp_path))
    assert {(a.a, a.b) for a in with_rfcl.answers} == {("auxss", "rfcl")}
    assert "auxss ahead" not in {a.verdict for a in with_rfcl.answers}


def test_make_study_rfcl_trains_both_on_every_task_at_the_studys_budgets_seeds_and_options():
    def cells(target, methods):
        return {(task, method): {key: value for key, value in sweep.items() if key not in ("--methods", "--envs")}
                for sweep in makefile_sweeps(target) for task in sweep["--envs"].split(",")
                for method in sweep["--methods"].split(",") if method in methods}

    study = cells("study", {"auxss"})
    rfcl = cells("study-rfcl", {"rfcl", "rfcl_reverse"})
    assert {task for task, _ in study} == set(lava_bridge_mj.SUITE)
    assert rfcl == {(task, method): options for (task, _), options in study.items()
                    for method in ("rfcl", "rfcl_reverse")}
    assert makefile_commands("study-rfcl", "export") == makefile_commands("study", "export")
