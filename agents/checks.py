"""Validation shared by every hyperparameter dataclass: one message format for each kind of bad value."""

from __future__ import annotations

from typing import Any

from lava_bridge_mj.checks import check_integer, check_number, check_real_array

__all__ = ["check_hidden_sizes", "check_integer", "check_number", "check_real_array"]


def check_hidden_sizes(sizes: Any) -> tuple[int, ...]:
    """The hidden layer widths as a tuple; ValueError unless a non-empty list of positive integers."""
    if (not isinstance(sizes, (list, tuple)) or not sizes
            or not all(isinstance(n, int) and not isinstance(n, bool) and n >= 1 for n in sizes)):
        raise ValueError(f"hidden_sizes must be a non-empty list of positive integers, got {sizes!r}")
    return tuple(sizes)
