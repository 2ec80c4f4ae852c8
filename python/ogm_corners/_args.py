"""Argument checks shared by the public API: integers taken from anything integral and refused, with the
argument's name, as a ``TypeError`` when not integral and a ``ValueError`` when out of range (the
extension's own conversion would raise an ``OverflowError`` that names nothing); sequences refused when
they are a single string (iterating one would give a name or a map per character)."""

from __future__ import annotations

import operator
import os
from typing import Any, List, Optional


def integer(name: str, value: Any, low: int = 0, high: Optional[int] = None) -> int:
    """``value`` as a plain ``int``: any integral (``int``, numpy integers, anything with ``__index__``)
    but ``bool`` (a flag passed where a count is meant), within ``[low, high]``."""
    if isinstance(value, bool):
        raise TypeError(f"{name} must be an int, got bool {value!r}")
    try:
        v = operator.index(value)
    except TypeError:
        raise TypeError(f"{name} must be an int, got {type(value).__name__} {value!r}") from None
    if v < low or (high is not None and v > high):
        what = f"{low} or more" if high is None else f"between {low} and {high}"
        raise ValueError(f"{name} must be {what}, got {v}")
    return v


def unsigned(name: str, value: Any, bits: int) -> int:
    """``value`` as a plain ``int`` that fits ``bits`` unsigned bits."""
    return integer(name, value, 0, 2**bits - 1)


def sequence(name: str, value: Any) -> List[Any]:
    """``value``'s items as a list, refusing a string, bytes or a path (one item, not a sequence of them)
    and anything not iterable."""
    if isinstance(value, (str, bytes, bytearray, os.PathLike)):
        raise TypeError(
            f"{name} must be a sequence (a list or a tuple), not a single {type(value).__name__} {value!r}"
        )
    try:
        return list(value)
    except TypeError:
        raise TypeError(f"{name} must be a sequence (a list or a tuple), got {type(value).__name__}") from None


def names(value: Any) -> List[str]:
    """Map names: a sequence of strings (not one string, which would be split into characters)."""
    out = sequence("names", value)
    for i, n in enumerate(out):
        if not isinstance(n, str):
            raise TypeError(f"names[{i}] must be a str, got {type(n).__name__} {n!r}")
    return out
