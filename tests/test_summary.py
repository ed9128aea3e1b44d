"""The Markdown summary of run directories, on synthetic metrics with hand-computed answers."""

import csv

import pytest

from lava_bridge_mj.eval import summary
from lava_bridge_mj.eval.runner import METRIC_FIELDS


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
    with pytest.raises(SystemExit):
        summary.main([str(tmp_path)])
    assert "holds no metrics.csv" in capsys.readouterr().err
