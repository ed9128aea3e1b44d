"""The training loop: train one method for one seed, or for K seeds at once, writing one run
directory per seed (eval/training/run_files.py lists its files). Every file is replaced
atomically, so an interrupted run never leaves a half-written one. The method (agents/methods.py)
decides the learner, the start strategy and how the demos are used; this loop reads only that.

K seeds of one configuration train together in one process (`train(config, dirs, seeds=...)`): one
`SAC` with stacked networks updates all of them in one batched step, and one vector env
(`LavaBridgeVectorEnv`; `ResetToStateVectorEnv` for any other MuJoCo gymnasium env) steps their
episodes (sub-env i is seed i's, reset to the starts its strategy chooses), each seed with its own
start strategy, replay buffer, RNGs and directory. A seed's files are the same as if it had trained
alone (tests/test_runner.py checks it), and its checkpoint holds only its own state, so it can be
resumed alone or in another batch. The seeds of a batch checkpoint together after each evaluation,
mid-episode (the physics state (qpos, qvel; another env's full state) and the episode's step count are saved, and restoring
them replays the uninterrupted run exactly). A kill between two seeds' checkpoint writes leaves
some seeds one checkpoint ahead; each keeps the previous one too, and a resume picks the newest step
every seed of the batch has. A resume may raise `steps`: a finished run extended to a larger budget
equals one trained to it in one go (`RunConfig.continues`).
"""

from __future__ import annotations

import dataclasses
import sys
import time
from collections.abc import Sequence
from contextlib import ExitStack, contextmanager
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from lava_bridge_mj.agents.jsrl import JSRLGuide
from lava_bridge_mj.agents.methods import METHODS, learner_class
from lava_bridge_mj.agents.replay_buffer import ReplayBuffer
from lava_bridge_mj.agents.seed_batch import stack_batches
from lava_bridge_mj.checks import check_integer
from lava_bridge_mj.eval.arguments import Interrupted, format_seeds, handling_signals, stop_reason
from lava_bridge_mj.eval.training.config import RunConfig, check_batch_fits
from lava_bridge_mj.eval.training.evaluate import EVAL_STARTS, evaluate, members_at_once
from lava_bridge_mj.eval.training.provenance import code_provenance
from lava_bridge_mj.eval.training.run_files import (CHECKPOINTS, VIDEOS, DamagedFileError, RunDirectoryError,
                                                    append_provenance, check_run_directory, check_strategy_unchanged,
                                                    locked, read_checkpoint, remove_leftovers, remove_run, write_config)
from lava_bridge_mj.eval.training.seed_run import SeedRun
from lava_bridge_mj.eval.training.tracking import (TRAIN_LOG_EVERY, ProgressReport, check_sinks, open_sink,
                                                   training_scalars, wandb_settings)


class RunInterrupted(Exception):
    """SIGINT or SIGTERM stopped training; a checkpoint was written first, so --resume continues."""

    def __init__(self, signum: int, step: int):
        super().__init__(f"{stop_reason(signum)} at step {step} after writing a checkpoint")
        self.signum, self.step = signum, step


def make_agent(config: RunConfig, seeds: Sequence[int], learner: str | None = None, device: str = "cpu"):
    """The method's learner (or the learner called `learner`: JSRL's guide) for `seeds`, stacked in one
    agent on the torch `device`."""
    learner = learner or METHODS[config.method].learner
    obs_dim, act_dim = config.dims()
    return learner_class(learner)(obs_dim, act_dim, getattr(config, learner), seeds=seeds, device=device)


def demo_buffer(config: RunConfig) -> ReplayBuffer:
    """The demo set's transitions (HySAC's offline buffer, JSRL's guide's and the offline methods'
    data): exactly full, never written again.

    The shipped demos carry the default rewards (+1 at the goal, 0 otherwise; the expert never
    touches lava); they are relabelled with the run's env rewards so both buffers agree. Another env's
    demos keep their rewards, and their actions are rescaled from the env's Box bounds to the
    learners' [-1, 1], as the vector env rescales the other way."""
    demos = config.load_demos()
    env = config.make_env()
    actions = demos["actions"]
    if config.lava_bridge:
        rewards = np.where(demos["rewards"] == 1.0, env.goal_reward, env.step_reward)
    else:
        rewards = demos["rewards"]
        low, high = env.action_space.low.astype(np.float64), env.action_space.high.astype(np.float64)
        actions = ((actions - low) / (high - low) * 2.0 - 1.0).astype(np.float32)
    env.close()
    buffer = ReplayBuffer(len(rewards), demos["observations"].shape[1], actions.shape[1])
    for transition in zip(demos["observations"], actions, rewards, demos["next_observations"],
                          demos["terminations"]):
        buffer.add(*transition)
    return buffer


class Run:
    """K seeds of one configuration training in lockstep, with the loop that advances them.

    `seed_runs[i]` holds seed i's env, strategy, buffers and files; `agent` is the method's learner
    (SAC, BC or IQL) over all seeds, `guide` JSRL's guide (agents/jsrl.py) for a method that has one.
    `rows` and `strategy` are the first seed's (the single-seed case). The learners' networks live on
    the torch `device`; the envs, buffers and start strategies on the CPU.
    """

    def __init__(self, configs: list[RunConfig], out_dirs: list[str | Path], device: str = "cpu"):
        if not configs or len(configs) != len(out_dirs):
            raise ValueError(f"expected one run directory per configuration, got {len(configs)} and {len(out_dirs)}")
        shared = [{**c.to_dict(), "seed": None} for c in configs]
        if any(values != shared[0] for values in shared):
            raise ValueError("the seeds of one batch must share every setting but the seed")
        seeds = [c.seed for c in configs]
        if len(set(seeds)) != len(seeds):
            raise ValueError(f"seeds must be distinct, got {seeds}")
        self.config = configs[0]
        self.method = method = METHODS[self.config.method]
        probe = self.config.make_env()  # an env of the task for the strategies' own rollouts (Omega-SS)
        # every seed's evaluation episodes in one vector env (a group of seeds at a time if they need
        # more sub-envs than fit: `members_at_once`); episodes are reset with fixed seeds before every round
        episodes = self.config.eval_episodes
        seeds_at_once = members_at_once(len(configs), episodes, None if self.config.lava_bridge else probe)
        self.eval_envs = self.config.make_vector_env(seeds_at_once * episodes)
        # the seeds share the config's demo set; the buffer is never written, so one copy serves all
        demos = demo_buffer(self.config) if method.demos != "none" else None
        # one vector env steps every seed's episode: sub-env i is seed i's, seeded with that seed
        self.envs = self.config.make_vector_env(len(configs))
        self.seed_runs = [SeedRun(c, d, probe=probe, envs=self.envs, index=i, demos=demos)
                          for i, (c, d) in enumerate(zip(configs, out_dirs))]
        self._start_episodes(np.ones(len(configs), dtype=bool), seeds=seeds)
        self.device = device
        self.agent = make_agent(self.config, seeds, device=device)
        self.guide = None
        if method.demos == "guide":
            self.guide = JSRLGuide(self.config.jsrl, make_agent(self.config, seeds, self.config.jsrl.guide, device),
                                   seeds)
        self.step = 0
        self.elapsed = 0.0  # wall time of earlier sessions of this run
        self.stop_signal: int | None = None  # set by SIGINT/SIGTERM: checkpoint and stop after this step
        self.active = np.ones(len(configs), dtype=bool)  # False: the seed diverged and stopped
        self.diverged: dict[int, int] = {}  # seed -> the step it stopped at
        self.sinks: list[list] = [[] for _ in configs]  # each seed's tracking sinks (eval/training/tracking.py)
        self.log_every = TRAIN_LOG_EVERY  # steps between the sinks' training scalars
        self.video_env = None  # renders each evaluation's rollouts, when tracking asks for videos
        self.video_frame = None  # and draws each frame of them (eval/video.py's video_env)

    # single-seed conveniences
    @property
    def rows(self) -> list[dict[str, float]]:
        return self.seed_runs[0].rows

    @property
    def strategy(self):
        return self.seed_runs[0].strategy

    # --- the loop -------------------------------------------------------------------------------
    def train(self, progress: bool | Path = True) -> None:
        """Advance to config.steps, then write final.pt; RunInterrupted after a checkpoint on a signal."""
        with self._stop_on_signals():
            self._train(progress)

    @contextmanager
    def _stop_on_signals(self):
        """SIGINT/SIGTERM ask the loop to checkpoint and stop after the current step; a second signal
        stops at once, losing only the work since the last checkpoint."""
        def request_stop(signum, frame):
            if self.stop_signal is not None:
                raise Interrupted(signum)
            self.stop_signal = signum

        with handling_signals(request_stop):
            yield

    def _train(self, progress: bool | Path) -> None:
        config, seed_runs = self.config, self.seed_runs
        report = ProgressReport(progress, self.step, config.steps) if isinstance(progress, (str, Path)) else None
        if report is not None:
            report.write(self.step, force=True)  # at once: a sweep says where a resumed job starts
        online = self.method.online
        learning_starts = config.sac.learning_starts if online else 0
        act_dim = self.envs.single_action_space.shape[0]
        start_time = time.perf_counter() - self.elapsed
        if self.guide is not None and not self.guide.trained:
            self.guide.fit(self.seed_runs[0].demos, getattr(config, config.jsrl.guide).batch_size)
            self.elapsed = time.perf_counter() - start_time
            self.save()  # the guide's training is not repeated by a resume
        session = (self.step, time.perf_counter())  # where this process's training loop began: the sinks' steps/s
        seeds = ", ".join(str(s) for s in self.agent.seeds)
        bar = tqdm(total=config.steps, initial=self.step, disable=progress is not True, unit="step",
                   desc=f"{config.method} seed{'s' if len(seed_runs) > 1 else ''} {seeds}", dynamic_ncols=True)
        while self.step < config.steps:
            if online:  # offline methods only update
                if self.step < learning_starts:
                    actions = [s.rng.uniform(-1.0, 1.0, act_dim).astype(np.float32) for s in seed_runs]
                else:
                    actions = self.agent.act(np.stack([s.obs for s in seed_runs]))
                if self.guide is not None:  # JSRL: the guide acts for the first h steps of each episode
                    actions = self.guide.act(np.stack([s.obs for s in seed_runs]),
                                             [s.selector.episode_length for s in seed_runs], actions)
                actions = np.asarray(actions, dtype=np.float32)
                diverged = self.active & ~np.isfinite(actions).all(axis=1)
                if diverged.any():
                    self._stop_diverged(diverged, f"its policy's action {actions[diverged.argmax()]} is not finite")
                if not self.active.all():
                    actions[~self.active] = 0.0  # a stopped seed's sub-env idles; its transitions are dropped
                next_obs, rewards, terminated, truncated, info = self.envs.step(actions)
                ended = np.array([active and s.observe(self.step + 1, a, r, o, term, trunc, success)
                                  for s, active, a, r, o, term, trunc, success in zip(
                                      seed_runs, self.active, actions, rewards, next_obs, terminated, truncated,
                                      info["is_success"])])
                if ended.any():
                    if self.guide is not None:
                        for i in np.flatnonzero(ended):
                            self.guide.curricula[i].record(info["is_success"][i])
                    self._start_episodes(ended)
            self.step += 1
            if self.step >= learning_starts:
                stats = self.agent.update(stack_batches([s.sample() for s in seed_runs]))
                for i in np.flatnonzero(self.active):
                    seed_runs[i].last_update = {name: float(values[i]) for name, values in stats.items()}
            if self.step % self.log_every == 0 and any(self.sinks):
                self._log_training(session, start_time)
            evaluation_due = self.step % config.eval_every == 0 or self.step == config.steps
            if evaluation_due:
                self.elapsed = time.perf_counter() - start_time
                rows = self.evaluate()
                returns = [r["train_return"] for r in rows if np.isfinite(r["train_return"])]
                if rows:
                    p0, ood = (np.mean([r[f"success_{start}"] for r in rows]) for start in ("p0", "ood"))
                    bar.set_postfix(p0=f"{p0:.2f}", ood=f"{ood:.2f}", ret=f"{np.mean(returns):.2f}" if returns else "-")
                    if report is not None:
                        report.evaluated(p0, ood)
            if not self.active.any():
                break  # every seed stopped: nothing left to train
            if evaluation_due or self.stop_signal is not None:
                self.elapsed = time.perf_counter() - start_time
                self.save()
                if self.stop_signal is not None:
                    bar.close()
                    raise RunInterrupted(self.stop_signal, self.step)
            bar.update(1)
            if report is not None and (evaluation_due or self.step % 100 == 0):
                report.write(self.step, force=evaluation_due)
        bar.close()
        self.elapsed = time.perf_counter() - start_time
        self.save("final.pt")

    def _log_training(self, session: tuple[int, float], start_time: float) -> None:
        """Each active seed's training scalars to its sinks (eval/training/tracking.py): read from what the loop
        keeps anyway, so logging changes nothing in training."""
        now = time.perf_counter()
        fps = (self.step - session[0]) / max(now - session[1], 1e-9)
        for i in np.flatnonzero(self.active):
            seed_run = self.seed_runs[i]
            train = dict(seed_run.last_update)
            if self.guide is not None:
                train["guide_horizon"] = self.guide.curricula[i].horizon
            scalars = training_scalars(train, seed_run.episode_log, {"fps": fps, "episodes": seed_run.episodes,
                                                                     "time_elapsed": now - start_time})
            for sink in self.sinks[i]:
                sink.log_training(self.step, scalars)

    def _stop_diverged(self, mask: np.ndarray, reason: str) -> None:
        """Stop the seeds in `mask` whose networks diverged: they write nothing more (their files keep
        their last checkpoint and evaluation) while the rest of the batch trains on unchanged, since
        every seed's slice of the batched networks is updated from its own loss alone."""
        for i in np.flatnonzero(mask):
            seed_run = self.seed_runs[i]
            self.active[i] = False
            self.diverged[seed_run.config.seed] = self.step
            last = seed_run.rows[-1]["step"] if seed_run.rows else None
            kept = f"its files keep step {last}" if last is not None else "it had not been evaluated yet"
            print(f"warning: seed {seed_run.config.seed} stopped at step {self.step}: {reason} (its networks "
                  f"diverged); {kept}; the other seeds go on", file=sys.stderr, flush=True)

    def _start_episodes(self, mask: np.ndarray, seeds: Sequence[int] | None = None) -> None:
        """Reset the sub-envs in `mask` to the starts their seeds' strategies choose (a candidate
        state, or the env's own p0 start); `seeds` (one per sub-env) reseeds their env RNGs first."""
        starts = [s.selector.choose() if m else None for s, m in zip(self.seed_runs, mask)]
        from_state = np.array([m and start is not None for m, start in zip(mask, starts)])
        seed_list = list(seeds) if seeds is not None else None
        obs = None
        if from_state.any():
            chosen = next(start for start in starts if start is not None)
            states = np.stack([start if start is not None else np.zeros_like(chosen) for start in starts])
            obs, _ = self.envs.reset(seed=seed_list, options={"state": states, "reset_mask": from_state})
        if (mask & ~from_state).any():
            obs, _ = self.envs.reset(seed=seed_list, options={"reset_mask": mask & ~from_state})
        for seed_run, m, o in zip(self.seed_runs, mask, obs):
            if m:
                seed_run.obs = o
                seed_run.episode_start = (float(o[0]), float(o[1]))

    def evaluate(self) -> list[dict[str, float]]:
        """Each seed's deterministic policy on the fixed p0 and ood episodes; rows written to each run.
        A start the env does not offer (`start_names`: another env offers p0, and ood where it declares
        one) scores NaN."""
        scores = {}
        for start in EVAL_STARTS:
            members = np.flatnonzero(self.active)  # a seed whose policy diverged stops evaluating too
            if start not in self.eval_envs.start_names:
                scores[start] = {i: {"success": float("nan"), "return": float("nan")} for i in members}
                continue
            scores[start], diverged = evaluate(self.agent, self.eval_envs, start, self.config.eval_episodes, members,
                                               horizon=self.eval_envs.max_episode_steps)
            for i, reason in sorted(diverged.items()):
                self._stop_diverged(np.arange(len(self.seed_runs)) == i, reason)
        rows = []
        for i, seed_run in enumerate(self.seed_runs):
            if not self.active[i]:
                continue
            p0, ood = (scores[start][i] for start in EVAL_STARTS)
            actor = {name: tensor[i:i + 1].to("cpu", copy=True)  # a CPU snapshot: it loads anywhere
                     for name, tensor in self.agent.actor.state_dict().items()}
            horizon = self.guide.curricula[i].horizon if self.guide is not None else float("nan")
            rows.append(seed_run.record(self.step, p0, ood, actor, self.elapsed, horizon))
            if self.sinks[i] or self.video_env is not None:
                self._track(i, rows[-1])
        return rows

    @contextmanager
    def tracking(self, sinks: Sequence[str], videos: bool = False, log_every: int = TRAIN_LOG_EVERY,
                 wandb: dict[str, str] | None = None):
        """Each seed logs its training scalars every `log_every` steps and its evaluations to `sinks`
        (eval/training/tracking.py; `wandb`: the W&B sink's wandb_settings()) while the block runs, with the
        rollouts of each evaluation as videos/step_N.mp4 when `videos`; closed however the block ends."""
        self.log_every = check_integer("log_every", log_every, 1)
        if videos:
            from lava_bridge_mj.eval.video import video_env

            self.video_env, self.video_frame = video_env(self.config.env_id, self.config.env)
        label = f"{self.config.method} on {self.config.env_id}"
        try:
            for i, seed_run in enumerate(self.seed_runs):
                self.sinks[i] = [open_sink(name, seed_run.dir, seed_run.config.to_dict(), label, self.step, wandb)
                                 for name in sinks]
            yield
        finally:
            for sink in (sink for seed_sinks in self.sinks for sink in seed_sinks):
                sink.close()
            self.sinks = [[] for _ in self.seed_runs]
            if self.video_env is not None:
                self.video_env.close()
                self.video_env = None

    def _track(self, i: int, row: dict[str, float]) -> None:
        seed_run, video = self.seed_runs[i], None
        if self.video_env is not None:
            from lava_bridge_mj.eval.video import record_rollouts

            video = seed_run.dir / VIDEOS / f"step_{self.step}.mp4"
            record_rollouts(self.video_env, self.policy(i), video, episodes_per_start=1, frame=self.video_frame)
        for sink in self.sinks[i]:
            sink.log(row, seed_run.strategy.probabilities, video)

    def policy(self, i: int = 0):
        """Seed i's deterministic policy: observations (n, 4) or (4,) -> actions (n, 2) or (2,)."""
        return self.agent.policy(i)

    # --- checkpoints ----------------------------------------------------------------------------
    def save(self, name: str = "checkpoint.pt") -> None:
        for i, seed_run in enumerate(self.seed_runs):
            if not self.active[i]:
                continue  # a diverged seed keeps its last good checkpoint
            state = seed_run.state(self.step, self.elapsed, self.agent.seed_state(i))
            if self.guide is not None:
                state.update(self.guide.seed_state(i))
            seed_run.save(state, name)

    def resume(self) -> None:
        """Continue from the newest checkpoint step that every seed has (see the module docstring);
        from the start if some seed has none. A damaged checkpoint is moved aside (NAME.damaged) with a
        one-line warning and the seed continues from its other one; a seed whose checkpoints are all
        damaged stops the resume, before anything changes."""
        available, damaged = [], []
        for seed_run in self.seed_runs:
            found, bad = {}, []
            for name in CHECKPOINTS:
                path = seed_run.dir / name
                if path.exists():
                    try:
                        state = read_checkpoint(path, seed_run.config)
                    except DamagedFileError as error:
                        bad.append((path, error))
                        continue
                    found[state["step"]] = state
            if bad and not found:
                raise DamagedFileError(f"every checkpoint of {seed_run.dir} is damaged ({'; '.join(map(str, (e for _, e in bad)))}); "
                                       "its run cannot continue: train it again with --overwrite, or into another directory")
            available.append(found)
            damaged.extend(bad)
        if all(available):
            common = set.intersection(*(set(found) for found in available))
            if not common:
                steps = {str(s.dir): sorted(found) for s, found in zip(self.seed_runs, available)}
                raise ValueError(f"the seeds' checkpoints are at different steps {steps}; resume them in separate batches")
            if max(common) > self.config.steps:
                raise ValueError(f"the checkpoints of {', '.join(str(s.dir) for s in self.seed_runs)} are at step "
                                 f"{max(common)}, past steps={self.config.steps}; a run continues to more steps, "
                                 "never fewer")
        for path, error in damaged:  # set aside, so the next checkpoint rotation cannot keep it as the fallback
            path.replace(path.with_name(path.name + ".damaged"))
            print(f"warning: {error}; moved it to {path.name}.damaged and continuing from the other checkpoint",
                  file=sys.stderr, flush=True)
        if not all(available):
            return
        self.step = max(common)
        states = [found[self.step] for found in available]
        self.elapsed = max(state["elapsed"] for state in states)
        self.agent.load_seed_states([state["agent"] for state in states])
        if self.guide is not None:
            self.guide.load_seed_states(states)
        for seed_run, state in zip(self.seed_runs, states):
            try:
                seed_run.load(state)
            except ValueError as error:  # a state this code cannot continue, written by another version
                raise ValueError(f"the checkpoint of {seed_run.dir} at step {self.step} cannot be resumed: {error}; "
                                 "continue it with the version that wrote it, or start a new run directory") from None


def train(config: RunConfig, out_dir: str | Path | Sequence[str | Path], *, seeds: Sequence[int] | None = None,
          resume: bool = False, overwrite: bool = False, progress: bool | str | Path = True, log: Sequence[str] = (),
          log_videos: bool = False, log_every: int = TRAIN_LOG_EVERY, wandb: dict[str, str] | None = None,
          device: str = "cpu") -> Run:
    """Train `config` into `out_dir` and return the finished Run.

    With `seeds`, train those seeds of `config` together in one batch, seed seeds[i] into out_dir[i]
    (a sequence of directories, one per seed); each directory is what a single-seed run would write.

    A directory holding another run's results is refused (RunDirectoryError) unless `resume` (continue
    from its checkpoints; the configuration must match) or `overwrite` (remove that run's files first).
    While training, every directory is locked against a second process.

    `progress`: a progress bar (True), none (False), or the path of a `ProgressReport` file (a sweep's jobs).
    `log` names live tracking sinks ("tensorboard", "wandb": eval/training/tracking.py) that each seed's
    training scalars (every `log_every` steps) and evaluations go to as well; `log_videos` writes each
    evaluation's rollouts from p0 and ood to videos/step_N.mp4 (and to the sinks). `wandb` sets the
    W&B runs' {"project", "entity", "group", "name"} (over the WANDB_* environment variables; only
    with the "wandb" sink).

    `device`: the torch device the learners train on ("cpu", "cuda", "cuda:N"); a run option like
    torch's thread count, not part of the configuration, so provenance.json records it per session.
    A run continues only on the device type it was trained on (agents/seed_batch.py).
    """
    log = check_sinks(log)
    log_every = check_integer("log_every", log_every, 1)
    if wandb is not None and "wandb" not in log:
        raise ValueError(f"wandb settings {wandb!r} need the wandb sink: log=('wandb',)")
    wandb = wandb_settings(wandb) if "wandb" in log else None
    check_batch_fits(config, 1 if seeds is None else len(seeds))
    if seeds is None:
        configs, dirs = [config], [Path(out_dir)]
    else:
        configs = [dataclasses.replace(config, seed=seed) for seed in seeds]
        dirs = [Path(d) for d in ([out_dir] if isinstance(out_dir, (str, Path)) else out_dir)]
        if len(dirs) != len(configs):
            raise ValueError(f"expected one run directory per seed ({len(configs)}), got {len(dirs)}")
    run = Run(configs, dirs, device)  # builds everything (and checks strategy parameters) before touching disk
    for directory in dirs:
        try:
            directory.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise RunDirectoryError(f"cannot create run directory {directory}: {error.strerror or error}") from None
    with ExitStack() as locks:
        for directory in dirs:
            locks.enter_context(locked(directory))
        for seed_config, directory in zip(configs, dirs):  # check every directory before changing any
            check_run_directory(seed_config, directory, resume, overwrite)
        if overwrite:
            for directory in dirs:
                remove_run(directory)
        if resume:
            for directory in dirs:
                remove_leftovers(directory)
            run.resume()
            for seed_run in run.seed_runs if run.step > 0 else ():  # a run restarted from 0 changes nothing
                check_strategy_unchanged(seed_run.dir, seed_run.strategy_settings)
            if 0 < run.step < config.steps:
                print(f"{config.method} seed{'s' if len(configs) > 1 else ''} {format_seeds(run.agent.seeds)}: "
                      f"resuming from step {run.step:,}", flush=True)
        for seed_config, directory in zip(configs, dirs):
            if run.step < config.steps:
                # the final.pt of a smaller budget goes before config.json names the larger one: else an
                # extension stopped short of its end would read as finished and a rerun would skip it
                (directory / "final.pt").unlink(missing_ok=True)
            write_config(directory, seed_config.to_dict())
        if run.step < config.steps:  # a finished run resumed at its budget trains nothing: no session
            code = code_provenance()
            started = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
            for seed_run in run.seed_runs:
                session = {"from_step": run.step, "to_step": config.steps, "started": started, "code": code,
                           "device": str(device), "strategy": seed_run.strategy_settings}
                append_provenance(seed_run.dir, session, resume)
        with run.tracking(log, log_videos, log_every, wandb):
            run.train(progress=progress)
    return run
