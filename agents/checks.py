"""Validation shared by every hyperparameter dataclass: one message format for each kind of bad value,
and a check that a configuration's arrays can fit in the machine's memory at all."""

from __future__ import annotations

import os
from typing import Any

from lava_bridge_mj.checks import check_integer, check_number, check_real_array

__all__ = ["available_memory", "check_fits_in_memory", "check_hidden_sizes", "check_integer", "check_number",
           "check_real_array", "minibatch_floats", "physical_memory"]

FLOAT_BYTES = 4
"""Replay buffers and networks hold float32."""


def check_hidden_sizes(sizes: Any) -> tuple[int, ...]:
    """The hidden layer widths as a tuple; ValueError unless a non-empty list of positive integers."""
    if (not isinstance(sizes, (list, tuple)) or not sizes
            or not all(isinstance(n, int) and not isinstance(n, bool) and n >= 1 for n in sizes)):
        raise ValueError(f"hidden_sizes must be a non-empty list of positive integers, got {sizes!r}")
    return tuple(sizes)


def physical_memory() -> int | None:
    """The machine's physical memory in bytes (os.sysconf), or None where the OS does not say."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, OSError, ValueError):  # no sysconf (Windows) or no such name
        return None


def available_memory() -> int | None:
    """The bytes that can still be allocated here without swapping: Linux's estimate MemAvailable
    (/proc/meminfo: free memory plus what the page cache can give back); elsewhere the physical
    memory; None where neither is known."""
    try:
        with open("/proc/meminfo") as meminfo:
            for line in meminfo:
                name, _, value = line.partition(":")
                if name == "MemAvailable":
                    return int(value.split()[0]) * 1024  # kB
    except (OSError, ValueError, IndexError):
        pass
    return physical_memory()


def minibatch_floats(batch_size: int, obs_dim: int, act_dim: int, hidden_sizes: tuple[int, ...],
                     network_passes: int) -> int:
    """The floats one gradient update over a minibatch of `batch_size` transitions holds at least: the
    transitions (observation, action, reward, next observation, termination) twice, as drawn and as
    stacked over the seeds, and one activation per hidden unit for each of the `network_passes`
    forward passes of a network over the minibatch that the update's first loss needs."""
    return batch_size * (2 * (2 * obs_dim + act_dim + 2) + network_passes * sum(hidden_sizes))


def check_fits_in_memory(*configs: Any, seeds: int, obs_dim: int, act_dim: int,
                         memory: int | None = None) -> None:
    """ValueError unless the arrays of `configs` (e.g. a run's SACConfig, and the IQLConfig of its JSRL
    guide; anything with a `memory_bytes(seeds, obs_dim, act_dim)` method giving bytes by field) for
    `seeds` seeds trained together fit in `memory` bytes (default: the memory available here,
    `available_memory`). The estimate, each config's `memory_bytes` summed, is a lower bound:
    checkpoint copies, the envs and the rest of the process come on top. So a configuration refused
    here cannot run, and fails at once, before anything is written, with a message naming the field
    that takes the most and the memory needed, instead of a MemoryError (or the kernel's OOM kill,
    which may pick another process) minutes later."""
    memory = available_memory() if memory is None else memory
    if memory is None:
        return
    parts = [(config, field, size) for config in configs
             for field, size in config.memory_bytes(seeds, obs_dim, act_dim).items()]
    total = sum(size for _, _, size in parts)
    if total <= memory:
        return
    config, field, _ = max(parts, key=lambda part: part[2])
    shares = ", ".join(f"{type(c).__name__}.{f}: {_format_bytes(s)}" for c, f, s in parts)
    who = "1 seed needs" if seeds == 1 else f"{seeds} seeds need"
    raise ValueError(f"{type(config).__name__}.{field}={getattr(config, field)!r} does not fit in memory: "
                     f"{who} at least {_format_bytes(total)} ({shares}), "
                     f"more than the {_format_bytes(memory)} of memory available here")


def _format_bytes(size: float) -> str:
    units = ("B", "KiB", "MiB", "GiB", "TiB")
    power = 0
    while size >= 1024 and power < len(units) - 1:
        size, power = size / 1024, power + 1
    return f"{size:.1f} {units[power]}"
