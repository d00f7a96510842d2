"""`--only KEYS`: configuration keys and ranges, checked against the matrix without materialising ranges.

`--only 4,5,6,7` or `--only 12-14,27`. A range is kept as its two ends; it is resolved against the
protocol's keys, so `--only 4-400000000` costs as much as `--only 4-40`: every key in a range must exist,
and a message names at most `SHOWN` of the keys that do not (and how many there are).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

from ..errors import InvalidInput

SHOWN = 5
MAX_PARTS = 1000


@dataclass(frozen=True)
class KeySelection:
    """The parsed `--only` argument: (low, high) ranges, a single key being (k, k)."""

    ranges: tuple[tuple[int, int], ...]

    @classmethod
    def parse(cls, text: str) -> KeySelection:
        parts = [p for p in text.replace(" ", "").split(",") if p]
        if len(parts) > MAX_PARTS:
            raise InvalidInput(f"--only: more than {MAX_PARTS} keys or ranges; use ranges such as 12-14")
        ranges: list[tuple[int, int]] = []
        for part in parts:
            try:
                if "-" in part[1:]:
                    lo_text, hi_text = part.split("-", 1)
                    lo, hi = int(lo_text), int(hi_text)
                else:
                    lo = hi = int(part)
                if hi < lo or lo < 0 or len(part) > 40:
                    raise ValueError
            except ValueError:
                raise InvalidInput(
                    f"--only: {part[:40]!r} is not a configuration key or range (e.g. --only 4,5,6,7 or 12-14)"
                ) from None
            ranges.append((lo, hi))
        if not ranges:
            raise InvalidInput("--only: give at least one configuration key, e.g. --only 4,5,6,7")
        return cls(tuple(ranges))

    def text(self) -> str:
        """The selection as `--only` takes it, e.g. "4,5,12-14"."""
        return ",".join(str(lo) if lo == hi else f"{lo}-{hi}" for lo, hi in self.ranges)

    def select(self, keys: Iterable[int], file_name: str) -> list[int]:
        """The protocol keys chosen, sorted; `InvalidInput` naming the unknown ones if any is not a key."""
        known = sorted(set(keys))
        known_set = set(known)
        unknown: list[int] = []
        n_unknown = 0
        for lo, hi in _merged(self.ranges):
            inside = sum(1 for k in known if lo <= k <= hi)
            missing = (hi - lo + 1) - inside
            if missing <= 0:
                continue
            n_unknown += missing
            k = lo
            while len(unknown) < SHOWN and k <= hi:  # at most len(known) + SHOWN steps
                if k not in known_set and k not in unknown:
                    unknown.append(k)
                k += 1
        if n_unknown:
            more = f" and {n_unknown - len(unknown):,} more" if n_unknown > len(unknown) else ""
            span = f"{known[0]}-{known[-1]}" if known else "none"
            raise InvalidInput(
                f"--only: no configuration has key {', '.join(map(str, sorted(unknown)))}{more} "
                f"(keys in {file_name}: {span})"
            )
        return [k for k in known if any(lo <= k <= hi for lo, hi in self.ranges)]


def _merged(ranges: Iterable[tuple[int, int]]) -> list[tuple[int, int]]:
    """Overlapping or touching ranges joined, so no key is counted twice."""
    out: list[tuple[int, int]] = []
    for lo, hi in sorted(ranges):
        if out and lo <= out[-1][1] + 1:
            out[-1] = (out[-1][0], max(out[-1][1], hi))
        else:
            out.append((lo, hi))
    return out


def key_spans(keys: Iterable[int]) -> str:
    """Keys as runs: "1-8", "1-3, 5, 7-9" ("none" if empty)."""
    runs = _merged((k, k) for k in keys)
    return ", ".join(str(lo) if lo == hi else f"{lo}-{hi}" for lo, hi in runs) or "none"
