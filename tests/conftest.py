"""Shared test set-up.

The package picks EGL for off-screen rendering on headless machines, but only if it is imported
before mujoco: mujoco reads MUJOCO_GL once, at import, and falls back to GLFW, which aborts the
whole process (not an exception) when there is no display. Test modules import mujoco in any
order, so the choice is made here, before any of them is collected.
"""

import os

if "MUJOCO_GL" not in os.environ and not os.environ.get("DISPLAY"):
    os.environ["MUJOCO_GL"] = "egl"

import contextlib  # noqa: E402
import csv  # noqa: E402
import io  # noqa: E402
import re  # noqa: E402
import shlex  # noqa: E402
import shutil  # noqa: E402
import subprocess  # noqa: E402
from pathlib import Path  # noqa: E402

import pytest  # noqa: E402


def makefile_recipe(target):
    """The command lines of the Makefile's `target`, continuation lines joined and the Makefile's own
    `NAME := value` variables substituted as make would (others, such as $(MAKE), are left as they are):
    the Makefile is the one place the project's commands live, and tests read them from there."""
    makefile = (Path(__file__).resolve().parent.parent / "Makefile").read_text().replace("\\\n", " ")
    variables = dict(re.findall(r"^(\w+) := (.*)$", makefile, re.MULTILINE))

    def expand(text):
        return re.sub(r"\$\((\w+)\)", lambda m: expand(variables[m[1]]) if m[1] in variables else m[0], text)

    lines = re.search(rf"^{target}:.*\n((?:\t.*\n)+)", makefile, re.MULTILINE).group(1).splitlines()
    return [expand(line) for line in lines]


def makefile_commands(target, subcommand):
    """The argument lists of the `lava-bridge-bench SUBCOMMAND` lines of the Makefile's `target`."""
    prefix = f"lava-bridge-bench {subcommand} "
    return [shlex.split(line.split(prefix, 1)[1]) for line in makefile_recipe(target) if prefix in line]


def makefile_sweeps(target):
    """The options of each `lava-bridge-bench sweep` line of the Makefile's `target`: {"--envs": ..., ...}."""
    return [dict(zip(argv[::2], argv[1::2])) for argv in makefile_commands(target, "sweep")]


def study_report_command():
    """The argument list of the Makefile's `lava-bridge-bench report` line that makes docs/report_study."""
    [argv] = [argv for argv in makefile_commands("report", "report") if argv[argv.index("--out") + 1] == "docs/report_study"]
    return argv


def held_back_tasks():
    """Task -> "FIRST-LAST", for each task the study report reads at other seeds than its --seeds: the
    `--task-seeds` it is given while that task's seed extension trains."""
    argv = study_report_command()
    return dict(argv[i + 1].split("=", 1) for i, arg in enumerate(argv) if arg == "--task-seeds")


@pytest.fixture(scope="session", autouse=True)
def scratch_tmpdir():
    """TMPDIR, for this process and the ones it starts, a fresh directory removed at the end. A sweep's
    scratch directory outlives a test that SIGKILLs the sweep, SB3's logger makes a folder on every
    learn() and Ray its session: they go with it instead of piling up in /tmp. Short on purpose: Ray
    puts Unix sockets under it, whose paths may not exceed 107 bytes."""
    import tempfile

    scratch = tempfile.mkdtemp(prefix="lbm-tests-")
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("TMPDIR", scratch)
        patch.setattr(tempfile, "tempdir", None)  # gettempdir() caches; read TMPDIR again
        yield
    shutil.rmtree(scratch, ignore_errors=True)


@pytest.fixture(scope="session", autouse=True)
def one_torch_thread():
    """One torch thread for the whole session, as the CLI's default: a seed's numbers are then
    independent of its batch, and in-process training of tiny networks is not slowed by intra-op
    threads competing for a loaded 2-core machine. Tests whose assertions depend on it still name it.
    The previous setting is restored at the end."""
    import torch

    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


def metrics_without_wall_time(run_dir):
    """A run's metrics.csv rows as strings, without the one column that legitimately differs."""
    with open(run_dir / "metrics.csv") as f:
        return [{k: v for k, v in row.items() if k != "wall_time"} for row in csv.DictReader(f)]


def write_metric_runs(root, method, p0_by_seed, demos=500, ood=None, **config):
    """One run directory per seed under ROOT/METHOD-DEMOS-N, evaluations at steps 1000, 2000, ... with
    the given success from p0 and success from ood = `ood` or p0; config.json RunConfig's defaults
    changed by `config`. For tests of what the report makes of given numbers."""
    import json

    from lava_bridge_mj.eval.training.config import RunConfig
    from lava_bridge_mj.eval.training.run_files import METRIC_FIELDS

    for seed, p0 in p0_by_seed.items():
        directory = root / f"{method}-{demos}-{len(config)}" / f"seed{seed}"
        directory.mkdir(parents=True)
        (directory / "config.json").write_text(json.dumps(
            {**RunConfig().to_dict(), "method": method, "seed": seed, "demos": demos, **config}))
        with open(directory / "metrics.csv", "w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=METRIC_FIELDS)
            writer.writeheader()
            for i, value in enumerate(p0):
                writer.writerow({name: 0.0 for name in METRIC_FIELDS} | {
                    "step": 1000 * (i + 1), "success_p0": value, "success_ood": value if ood is None else ood[i]})


def groups_in(root):
    """The groups of the runs under `root`, as the report forms them."""
    from lava_bridge_mj.eval.analysis import aggregate

    return aggregate.group_runs(aggregate.find_runs(root))


def episode_rows(run_dir):
    """A run's episode log as csv.DictReader rows, read as the report reads it (compressed or plain)."""
    from lava_bridge_mj.eval.training import run_files

    return list(csv.DictReader(io.StringIO(run_files.read_episode_log(run_files.episode_log_file(run_dir)).decode())))


def interrupted_copy(full_dir, resumed_dir):
    """What a run killed mid-way leaves: config, the metrics and episode log written so far (with rows
    past the checkpoint), and the checkpoint before the last one as its latest."""
    resumed_dir.mkdir()
    for name in ("config.json", "metrics.csv", "episodes.csv.gz"):
        if (full_dir / name).exists():
            shutil.copy(full_dir / name, resumed_dir / name)
    shutil.copy(full_dir / "checkpoint.prev.pt", resumed_dir / "checkpoint.pt")


def flip_a_data_bit(path):
    """Flip one bit inside the largest tensor storage of a torch zip archive (a record under data/): a
    float's bits, not a header, and not the pickle, where the byte hit depends on how long the pickled
    objects are (the replay buffer, the episode counts) and may fall in a string torch then cannot decode."""
    import zipfile

    with zipfile.ZipFile(path) as archive:
        info = max((i for i in archive.infolist() if "/data/" in i.filename), key=lambda i: i.file_size)
    data = bytearray(path.read_bytes())
    offset = info.header_offset + 30 + len(info.filename.encode()) + len(info.extra)  # past the local header
    data[offset + info.file_size // 2] ^= 0x10
    path.write_bytes(bytes(data))


@contextlib.contextmanager
def read_only(directory):
    """`directory` made read-only for this process, root included: for a normal user its mode is
    0555; root writes through modes, so for root it is bind-mounted read-only onto itself (the kernel
    then refuses every write with EROFS). Skips only where neither is possible."""
    directory = str(directory)
    if os.geteuid() != 0:
        os.chmod(directory, 0o555)
        try:
            yield
        finally:
            os.chmod(directory, 0o755)
        return
    mounted = subprocess.run(["mount", "--bind", directory, directory], capture_output=True)
    if mounted.returncode != 0:
        pytest.skip(f"root cannot make {directory} read-only here: {mounted.stderr.decode().strip()}")
    try:
        subprocess.run(["mount", "-o", "remount,bind,ro", directory], check=True, capture_output=True)
        yield
    finally:
        subprocess.run(["umount", directory], check=True, capture_output=True)
