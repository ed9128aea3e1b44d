"""Checks of user-given numbers, shared by the env, the agents' configs and the start strategies:
one message format for each kind of bad value. Free of torch, so the env can use them."""

from __future__ import annotations

import math
import numbers
from typing import Any

import numpy as np

REAL_KINDS = "biuf"
"""numpy dtype kinds of real numbers (bool, signed and unsigned int, float); complex, object and
string arrays are refused rather than converted, which would drop an imaginary part or raise TypeError."""


def check_number(name: str, value: Any, low: float = 0.0, high: float = math.inf, *,
                 low_inclusive: bool = False, high_inclusive: bool = True) -> float:
    """`value` as a float; ValueError unless it is a finite real number in the interval, e.g.
    "gamma must be a number in (0, 1], got 1.5" or "lr must be a finite number > 0, got inf"."""
    number = math.nan
    if isinstance(value, numbers.Real) and not isinstance(value, bool):
        try:
            number = float(value)
        except OverflowError:  # an int beyond float's range
            pass
    above = number >= low if low_inclusive else number > low
    below = number <= high if high_inclusive else number < high
    if not (math.isfinite(number) and above and below):  # NaN fails every comparison too
        raise ValueError(f"{name} must be {_describe_interval(low, high, low_inclusive, high_inclusive)}, "
                         f"got {value!r}")
    return number


def _describe_interval(low: float, high: float, low_inclusive: bool, high_inclusive: bool) -> str:
    if math.isinf(low) and math.isinf(high):
        return "a finite number"
    if math.isinf(high):
        return f"a finite number {'>=' if low_inclusive else '>'} {low:g}"
    if math.isinf(low):
        return f"a finite number {'<=' if high_inclusive else '<'} {high:g}"
    return f"a number in {'[' if low_inclusive else '('}{low:g}, {high:g}{']' if high_inclusive else ')'}"


def check_integer(name: str, value: Any, minimum: int, maximum: int | None = None) -> int:
    """`value` as an int; ValueError unless it is an integer >= minimum (and <= maximum when given),
    e.g. "batch_size must be an integer >= 1, got 0"."""
    if (isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < minimum
            or (maximum is not None and value > maximum)):
        expected = f"an integer >= {minimum}" if maximum is None else f"an integer in [{minimum}, {maximum}]"
        raise ValueError(f"{name} must be {expected}, got {value!r}")
    return int(value)


def check_real_array(name: str, value: Any, shape: tuple[int, ...], *, finite: bool = True) -> np.ndarray:
    """`value` as a numpy array (not copied when it already is one); ValueError naming `name` unless it
    holds real numbers in the given shape, finite ones unless `finite` is False."""
    try:
        array = np.asarray(value)
    except (TypeError, ValueError):  # e.g. ragged nested lists
        array = np.empty(0, dtype=object)
    if array.dtype.kind not in REAL_KINDS:
        raise ValueError(f"{name} must be finite real numbers of shape {shape}, got {value!r}")
    if array.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got shape {array.shape}: {value!r}")
    if finite and not np.isfinite(array).all():
        raise ValueError(f"{name} must be finite, got {array}")
    return array
