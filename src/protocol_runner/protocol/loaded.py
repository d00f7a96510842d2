"""A loaded, validated protocol with its provenance, and the YAML locations its messages name."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from .schema import Protocol

#: A place in the protocol document: keys and list indices from the root.
Loc = tuple[str | int, ...]
#: A user's mistake: where it is, and what is wrong there.
Problem = tuple[Loc, str]


@dataclass(frozen=True)
class RigSource:
    """The rig file a protocol was checked against: its name in messages (`rigs/rsst.yaml`, `lab_rig.yaml`),
    its text exactly as read (archived as /rig), that text's sha256, the file it was read from and the
    line of every key (for messages that point into it)."""

    shown: str
    text: str
    sha256: str
    path: Path | None = field(default=None, compare=False)  # where it was read (messages only)
    lines: dict[Loc, int] = field(default_factory=dict, repr=False, compare=False)


@dataclass(frozen=True)
class LoadedProtocol:
    """A validated protocol with its provenance: the exact text and its sha256."""

    protocol: Protocol
    path: Path
    text: str
    sha256: str
    lines: dict[Loc, int] = field(default_factory=dict, repr=False, compare=False)
    shown: str = field(default="", repr=False, compare=False)  # the file's name in messages
    rig_source: RigSource = field(default_factory=lambda: RigSource("", "", ""), repr=False, compare=False)

    @property
    def base_dir(self) -> Path:
        """Relative paths in the protocol (trajectory and calibration files) are relative to this."""
        return self.path.parent


def line_for(lines: dict[Loc, int], loc: Loc) -> int | None:
    while True:
        if loc in lines:
            return lines[loc]
        if not loc:
            return None
        loc = loc[:-1]
