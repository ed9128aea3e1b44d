"""The Markdown summary of run directories, on synthetic metrics with hand-computed answers."""

import csv

import numpy as np
import pytest

from lava_bridge_mj.eval.analysis import summary
from lava_bridge_mj.eval.training.run_files import EPISODE_FIELDS, METRIC_FIELDS


def write_run(directory, p0, ood):
    directory.mkdir(parents=True)
    with open(directory / "metrics.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=METRIC_FIELDS)
        writer.writeheader()
        for i, (a, b) in enumerate(zip(p0, ood)):
            writer.writerow({name: 0.0 for name in METRIC_FIELDS} | {"step": 1000 * (i + 1), "success_p0": a, "success_ood": b})


def test_summary_of_a_batch_by_hand(tmp_path):
    write_run(tmp_path / "seed10", [0.0, 0.9, 1.0, 0.5], [0.0, 0.2, 0.6, 0.4])  # first >= 0.8 at 2000, best 1.0 at 3000
    write_run(tmp_path / "seed2", [0.0, 0.3, 0.3, 0.1], [0.0, 0.0, 0.1, 0.0])  # never; best 0.3 first at 2000
    text = summary.markdown(tmp_path)
    rows = [line for line in text.splitlines() if line.startswith("| seed")]
    assert rows[0] == "| seed2 | never | 0.30 (2,000) | 0.10 / 0.00 (at 4,000) |"  # seed order, not text order
    assert rows[1] == "| seed10 | 2,000 | 1.00 (3,000) | 0.50 / 0.40 (at 4,000) |"
    assert "| **all 2** | 1 of 2 reached it | mean 0.65 | mean 0.30 / 0.20 |" in text


def test_summary_refuses_a_directory_without_runs(tmp_path, capsys):
    assert summary.main([str(tmp_path)]) == 2
    assert "holds no metrics.csv" in capsys.readouterr().err


def test_start_room_share_by_hand(tmp_path):
    """Two candidates in the start room (x in [-5.5, -1.5] on the default layout), one on the bridge, one
    in the goal room; the share averages the logged evaluations up to the given step."""
    run = tmp_path / "seed0"
    write_run(run, [0.0, 0.0, 1.0], [0.0, 0.0, 0.5])
    (run / "config.json").write_text('{"env": {}}')
    states = np.array([[-4.0, 1.0, 0, 0], [-1.6, -1.9, 2.0, 0], [0.0, 0.0, 0, 0], [3.0, 0.0, 0, 0]])
    probabilities = np.array([[0.1, 0.2, 0.3, 0.4], [0.4, 0.4, 0.1, 0.1], [0.0, 0.0, 0.5, 0.5]])
    np.savez(run / "start_weights.npz", steps=np.array([1000, 2000, 3000]), states=states, probabilities=probabilities)
    assert summary.start_room_share(run, 2000) == pytest.approx((0.3 + 0.8) / 2)
    assert summary.start_room_share(run, 3000) == pytest.approx((0.3 + 0.8 + 0.0) / 3)
    assert np.isnan(summary.start_room_share(run, 500))  # nothing logged that early
    text = summary.markdown(tmp_path, start_room_until=2000)
    assert "| seed0 | 3,000 | 1.00 (3,000) | 1.00 / 0.50 (at 3,000) | 0.55 | 0 (-) |" in text  # no episode log
    assert text.splitlines()[-1].endswith("| mean 0.55 | 0 (-) |")
    # a narrower maze moves the start room: the layout comes from the run's own env settings
    (run / "config.json").write_text('{"env": {"bridge_length": 4.0}}')  # start room now x in [-6, -2]
    assert summary.start_room_share(run, 1000) == pytest.approx(0.1)


def test_start_room_share_is_nan_for_p0_runs(tmp_path):
    run = tmp_path / "seed0"
    write_run(run, [0.0], [0.0])
    (run / "config.json").write_text("{}")
    np.savez(run / "start_weights.npz", steps=np.array([1000]), states=np.zeros((3, 4)), probabilities=np.zeros((1, 0)))
    assert np.isnan(summary.start_room_share(run, 1000))


def test_curriculum_progress_of_a_reverse_curriculum_by_hand(tmp_path):
    """The 0.5K set's two goal-reaching demo episodes hold 169 and 170 states (indices 0-168 and 169-338).
    At step 1,000 each start is its episode's last state; at 2,000 the first episode's start is its state
    84 (half way back: (168 - 84) / 168) and the second's its first state (all the way back): 0.75 back
    on average; at 3,000 no demo state has weight, so every episode starts from p0."""
    import lava_bridge_mj
    from lava_bridge_mj.agents import goal_reaching_demos

    run = tmp_path / "seed0"
    write_run(run, [0.0, 0.5, 1.0], [0.0, 0.2, 0.5])
    (run / "config.json").write_text('{"method": "reverse_ss", "demos": 500}')
    states, ids = goal_reaching_demos(lava_bridge_mj.load_demos(500))
    assert np.array_equal(np.unique(ids, return_counts=True)[1], [169, 170])
    probabilities = np.zeros((3, len(states)))
    probabilities[0, [168, 338]] = probabilities[1, [84, 169]] = 0.5
    np.savez(run / "start_weights.npz", steps=np.array([1000, 2000, 3000]), states=states, probabilities=probabilities)
    assert summary.curriculum_progress(run, 1000) == (None, 0.0)
    assert summary.curriculum_progress(run, 2000) == (None, pytest.approx(0.75))
    assert summary.curriculum_progress(run, 3000) == (3000.0, None)
    assert summary.curriculum_progress(run, 500) == (None, None)  # nothing logged that early
    # weights that are not a reverse curriculum's: two starts on one episode
    probabilities[1, 85] = 0.25
    np.savez(run / "start_weights.npz", steps=np.array([1000, 2000, 3000]), states=states, probabilities=probabilities)
    with pytest.raises(ValueError, match=r"start_weights\.npz: demo episode 0 has 2 start states at step 2,000"):
        summary.curriculum_progress(run, 2000)
    # candidates that are not the run's demo episodes: nothing to measure how far back along
    np.savez(run / "start_weights.npz", steps=np.array([1000, 2000]), states=states[:30],
             probabilities=np.full((2, 30), 0.1))
    assert summary.curriculum_progress(run, 2000) == (None, None)


def test_start_room_needs_a_positive_step(tmp_path, capsys):
    write_run(tmp_path / "seed0", [0.0], [0.0])
    with pytest.raises(SystemExit):
        summary.main([str(tmp_path), "--start-room", "0"])
    assert "--start-room must be a step > 0, got 0.0" in capsys.readouterr().err


def write_episodes(run, rows):
    with open(run / "episodes.csv", "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(EPISODE_FIELDS)
        for i, (step, x, success) in enumerate(rows):
            writer.writerow([i + 1, step, -1, x, 0.0, 10, success, float(success)])


def test_start_room_training_episodes_by_hand(tmp_path):
    """Start-room episodes (x in [-5.5, -1.5]) up to the step, and the share of them that succeeded;
    pooled over seeds by episode count, not by averaging the seeds' shares."""
    for seed, rows in (("seed0", [(100, -4.0, 0), (300, -2.0, 1), (350, 0.0, 1), (900, 3.0, 0), (1500, -3.0, 0),
                                  (2500, -3.0, 1)]),
                       ("seed1", [(800, -5.0, 1)])):
        write_run(tmp_path / seed, [0.0, 1.0], [0.0, 0.5])
        (tmp_path / seed / "config.json").write_text('{"env": {}}')
        write_episodes(tmp_path / seed, rows)
    seed0 = tmp_path / "seed0"
    assert summary.start_room_episodes(seed0, 1000) == (2, 0.5)  # x = -4 (failed) and -2 (reached the goal)
    assert summary.start_room_episodes(seed0, 2000) == (3, pytest.approx(1 / 3))
    assert summary.start_room_episodes(seed0, 50)[0] == 0 and np.isnan(summary.start_room_episodes(seed0, 50)[1])
    text = summary.markdown(tmp_path, start_room_until=1000)
    assert "| seed0 | 2,000 | 1.00 (2,000) | 1.00 / 0.50 (at 2,000) | - | 2 (0.50) |" in text
    assert text.splitlines()[-1].endswith("| mean - | 3 (0.67) |")  # (1 + 1) of (2 + 1); no weights logged


def damage(run, case):
    """Break one file of a run directory written by write_run (with a config and start weights)."""
    metrics, weights = run / "metrics.csv", run / "start_weights.npz"
    if case == "no evaluation":
        metrics.write_text(",".join(METRIC_FIELDS) + "\n")
    elif case == "no column":
        metrics.write_text("step,success_p0\n1000,0.5\n")
    elif case == "not a number":
        metrics.write_text(metrics.read_text().replace("1000.0,", "x,", 1).replace("1000,", "x,", 1))
    elif case == "short row":
        metrics.write_text(metrics.read_text() + "5000,0.5\n")
    elif case == "not text":
        metrics.write_bytes(b"\xff\xfe\x00garbage")
    elif case == "truncated weights":
        weights.write_bytes(weights.read_bytes()[:300])
    elif case == "pickle weights":
        weights.write_bytes(b"not an npz at all")
    elif case == "weights of another shape":
        np.savez(weights, steps=np.array([1000]), states=np.zeros((4, 4)), probabilities=np.ones((1, 3)) / 3)
    elif case == "weights without states":
        np.savez(weights, steps=np.array([1000]), probabilities=np.ones((1, 3)) / 3)
    elif case == "bad config":
        (run / "config.json").write_text("{not json")
    elif case == "env not a dict":
        (run / "config.json").write_text('{"env": [1, 2]}')
    elif case == "bad env":
        (run / "config.json").write_text('{"env": {"bridge_length": "long"}}')
    elif case == "episodes without a column":
        (run / "episodes.csv").write_text("episode,step\n1,100\n")
    return {"no evaluation": metrics, "no column": metrics, "not a number": metrics, "short row": metrics,
            "not text": metrics, "bad config": run / "config.json", "env not a dict": run / "config.json",
            "bad env": run / "config.json", "episodes without a column": run / "episodes.csv"}.get(case, weights)


@pytest.mark.parametrize("case", ["no evaluation", "no column", "not a number", "short row", "not text",
                                  "truncated weights", "pickle weights", "weights of another shape",
                                  "weights without states", "bad config", "env not a dict", "bad env",
                                  "episodes without a column"])
def test_summary_of_a_damaged_run_is_one_line_naming_the_file(tmp_path, capsys, case):
    good, run = tmp_path / "good" / "seed0", tmp_path / "batch" / "seed0"
    for directory in (good, run):
        write_run(directory, [0.0, 0.9], [0.0, 0.5])
        (directory / "config.json").write_text('{"env": {}}')
        np.savez(directory / "start_weights.npz", steps=np.array([1000, 2000]), states=np.zeros((3, 4)),
                 probabilities=np.full((2, 3), 1 / 3))
        write_episodes(directory, [(100, -4.0, 0)])
    broken = damage(run, case)
    # the good directory first: its table must not be printed before the error either
    assert summary.main([str(good.parent), str(run.parent), "--start-room", "2000"]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    assert err.startswith("lava-bridge-bench summary: error: ") and str(broken) in err


@pytest.mark.parametrize("argv, message", [
    (["--threshold", "5"], "--threshold must be a success rate in [0, 1], got 5.0"),
    (["--threshold", "nan"], "--threshold must be a success rate in [0, 1], got nan"),
    (["--start-room", "inf"], "--start-room must be a step > 0, got inf"),
])
def test_summary_refuses_bad_options(tmp_path, capsys, argv, message):
    write_run(tmp_path / "seed0", [0.0], [0.0])
    with pytest.raises(SystemExit) as exit_:
        summary.main([str(tmp_path), *argv])
    assert exit_.value.code == 2 and message in capsys.readouterr().err


def test_summary_of_a_missing_directory_or_a_file(tmp_path, capsys):
    write_run(tmp_path / "seed0", [0.0], [0.0])
    for path in (tmp_path / "nowhere", tmp_path / "seed0" / "metrics.csv"):
        assert summary.main([str(path)]) == 2
        err = capsys.readouterr().err
        assert err == f"lava-bridge-bench summary: error: {path} is not a directory\n"


def test_curriculum_stall_counts_how_the_episodes_from_the_last_starts_ended_by_hand(tmp_path):
    """The 0.5K set's goal-reaching episodes hold 169 and 170 states (indices 0-168 and 169-338). At the
    last evaluation the starts are index 84 (85 steps back: limit 8 + 85 // 3 = 36) and index 169 (the
    second episode's first state, 170 back: limit 8 + 170 // 3 = 64). Episodes from other starts, or
    ending after `until`, do not count; one that reaches the goal on its limit's step is at the goal."""
    import json

    import lava_bridge_mj
    from lava_bridge_mj.agents import goal_reaching_demos

    run = tmp_path / "seed0"
    write_run(run, [0.0, 0.0], [0.0, 0.0])
    (run / "config.json").write_text('{"method": "reverse_ss", "demos": 500}')
    states, _ = goal_reaching_demos(lava_bridge_mj.load_demos(500))
    probabilities = np.zeros((2, len(states)))
    probabilities[0, [168, 338]] = probabilities[1, [84, 169]] = 0.5
    np.savez(run / "start_weights.npz", steps=np.array([1000, 2000]), states=states, probabilities=probabilities)
    episodes = [  # (step ended, start index, length, success)
        (100, 168, 1, 1), (1200, 84, 20, 1), (1300, 84, 36, 1), (1400, 84, 36, 0), (1500, 84, 35, 0),
        (1600, 169, 64, 0), (1700, 169, 10, 0), (1800, -1, 500, 0), (2500, 84, 3, 0)]
    with open(run / "episodes.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=EPISODE_FIELDS)
        writer.writeheader()
        for number, (step, start, length, success) in enumerate(episodes, 1):
            writer.writerow({"episode": number, "step": step, "start_index": start, "start_x": 0.0, "start_y": 0.0,
                             "length": length, "success": success, "return": float(success)})
    assert summary.curriculum_stall(run, 2000) == summary.CurriculumStall(6, goal=2, time_limit=2, lava=2)
    assert summary.curriculum_stall(run, 3000) == summary.CurriculumStall(7, goal=2, time_limit=2, lava=3)
    # the limits come from the settings the run recorded: ratio 5 gives 8 + 85 // 5 = 25 and 8 + 170 // 5 =
    # 42, which the episodes of length 35, 36 and 64 reached; with no ratio, the env's 500 steps none did
    for ratio, expected in ((5.0, summary.CurriculumStall(6, goal=2, time_limit=3, lava=1)),
                            (None, summary.CurriculumStall(6, goal=2, time_limit=0, lava=4))):
        (run / "provenance.json").write_text(json.dumps([{"strategy": {"demo_horizon_to_max_steps_ratio": ratio}}]))
        assert summary.curriculum_stall(run, 2000) == expected
    # a setting the strategy does not take (recorded by other code) is an error naming the run, not a TypeError
    (run / "provenance.json").write_text(json.dumps([{"strategy": {"reverse_step": 2}}]))
    with pytest.raises(ValueError, match=f"{run}: the recorded reverse_ss settings .*reverse_step"):
        summary.curriculum_stall(run, 2000)
    # before the second evaluation the starts were each episode's last state, from which one episode ran
    (run / "provenance.json").unlink()
    assert summary.curriculum_stall(run, 1500) == summary.CurriculumStall(1, goal=1, time_limit=0, lava=0)
    # a finished curriculum has no stall; nor has a run without an episode log
    probabilities[1] = 0.0
    np.savez(run / "start_weights.npz", steps=np.array([1000, 2000]), states=states, probabilities=probabilities)
    assert summary.curriculum_stall(run, 2000) is None
    (run / "episodes.csv").unlink()
    assert summary.curriculum_stall(run, 1500) is None
