"""Argument types shared by the ``qogi`` commands: each checks its value while
the command line is parsed, so a bad argument is a one-line usage error (exit
2) before any work, naming the option, the value and what is accepted."""

from __future__ import annotations

import argparse
import math


def _number(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None


def finite_float(text: str) -> float:
    """A finite number."""
    v = _number(text)
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"must be a finite number; got {text!r}")
    return v


def positive_float(text: str) -> float:
    """A finite number > 0."""
    v = finite_float(text)
    if not v > 0:
        raise argparse.ArgumentTypeError(f"must be > 0; got {text}")
    return v


def nonnegative_float(text: str) -> float:
    """A finite number >= 0."""
    v = finite_float(text)
    if v < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0; got {text}")
    return v


def fraction(text: str) -> float:
    """A number in [0, 1]."""
    v = finite_float(text)
    if not 0.0 <= v <= 1.0:
        raise argparse.ArgumentTypeError(f"must be within [0, 1]; got {text}")
    return v


def _integer(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None


def nonnegative_int(text: str) -> int:
    """A whole number >= 0 (seeds, thread counts: 0 = all cores)."""
    v = _integer(text)
    if v < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0; got {text}")
    return v


def seed(text: str) -> int:
    """A random seed: a whole number in [0, 2^64)."""
    v = nonnegative_int(text)
    if v >= 2**64:
        raise argparse.ArgumentTypeError(f"must be < 2^64; got {text}")
    return v
