"""Counts in messages: "1 configuration", "3 configurations", never "1 configurations"."""

from __future__ import annotations


def counted(n: int, noun: str, plural: str = "") -> str:
    """`n` and the noun, singular for exactly one: counted(1, "trial") = "1 trial", counted(0, "cycle") =
    "0 cycles"; `plural` where adding an "s" is wrong (counted(2, "trajectory", "trajectories"))."""
    return f"{n} {noun if n == 1 else plural or noun + 's'}"
