"""Argument types shared by the ``qogi`` commands: each checks its value while
the command line is parsed, so a bad argument is a one-line usage error (exit
2) before any work, naming the option, the value and what is accepted."""

from __future__ import annotations

import argparse
import math
from typing import Callable, TypeVar

_V = TypeVar("_V", int, float)


def _accepted(v: _V, ok: bool, accepted: str, text: str) -> _V:
    """v when ok; else the usage error "must be <accepted>; got <text>"."""
    if not ok:
        raise argparse.ArgumentTypeError(f"must be {accepted}; got {text}")
    return v


def _parsed(text: str, kind: Callable[[str], _V], what: str) -> _V:
    """kind(text); else the usage error "not <what>: <text>"."""
    try:
        return kind(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not {what}: {text!r}") from None


def finite_float(text: str) -> float:
    """A finite number."""
    v = _parsed(text, float, "a number")
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"must be a finite number; got {text!r}")
    return v


def positive_float(text: str) -> float:
    """A finite number > 0."""
    v = finite_float(text)
    return _accepted(v, v > 0, "> 0", text)


def nonnegative_float(text: str) -> float:
    """A finite number >= 0."""
    v = finite_float(text)
    return _accepted(v, v >= 0, ">= 0", text)


def fraction(text: str) -> float:
    """A number in [0, 1]."""
    v = finite_float(text)
    return _accepted(v, 0.0 <= v <= 1.0, "within [0, 1]", text)


def nonnegative_int(text: str) -> int:
    """A whole number >= 0 (seeds, thread counts: 0 = all cores)."""
    v = _parsed(text, int, "a whole number")
    return _accepted(v, v >= 0, ">= 0", text)


def seed(text: str) -> int:
    """A random seed: a whole number in [0, 2^64)."""
    v = nonnegative_int(text)
    return _accepted(v, v < 2**64, "< 2^64", text)
