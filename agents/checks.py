"""Validation shared by every hyperparameter dataclass: one message format for each kind of bad value."""

from __future__ import annotations

import math
from typing import Any


def check_number(name: str, value: Any, low: float = 0.0, high: float = math.inf, *,
                 low_inclusive: bool = False, high_inclusive: bool = True) -> None:
    """ValueError unless `value` is a real number in the interval, e.g. "gamma must be a number in (0, 1]"."""
    above = value >= low if low_inclusive else value > low
    below = value <= high if high_inclusive else value < high
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not (above and below):
        interval = f"{'[' if low_inclusive else '('}{low:g}, {high:g}{']' if high_inclusive else ')'}"
        raise ValueError(f"{name} must be a number in {interval}, got {value!r}")


def check_integer(name: str, value: Any, minimum: int, maximum: int | None = None) -> None:
    """ValueError unless `value` is an int >= minimum (and <= maximum), e.g. "batch_size must be an
    integer >= 1"."""
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum or (
            maximum is not None and value > maximum):
        expected = f"in [{minimum}, {maximum}]" if maximum is not None else f">= {minimum}"
        raise ValueError(f"{name} must be an integer {expected}, got {value!r}")


def check_hidden_sizes(sizes: Any) -> tuple[int, ...]:
    """The hidden layer widths as a tuple; ValueError unless a non-empty list of positive integers."""
    if (not isinstance(sizes, (list, tuple)) or not sizes
            or not all(isinstance(n, int) and not isinstance(n, bool) and n >= 1 for n in sizes)):
        raise ValueError(f"hidden_sizes must be a non-empty list of positive integers, got {sizes!r}")
    return tuple(sizes)
