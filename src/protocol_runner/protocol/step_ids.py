"""Step ids: the stable names of plan steps, used as unit file names, journal keys and in `--only` output.

Every id is made by `step_id`: the kind, then the set name, the configuration key (`k01`) and any
further parts, joined by colons (docs/protocol.md, "Plan and step ids").
"""

from __future__ import annotations


def step_id(kind: str, *parts: str | int, set_name: str | None = None, key: int | None = None) -> str:
    """`kind[:set_name][:kNN][:part...]`, e.g. `trial:k03:on:2`, `cal:A:before`, `process:k03`."""
    fields: list[str] = [kind]
    if set_name is not None:
        fields.append(set_name)
    if key is not None:
        fields.append(f"k{key:02d}")
    fields += [str(p) for p in parts]
    return ":".join(fields)


def calibration_id(set_name: str, when: str) -> str:
    return step_id("cal", when, set_name=set_name)


def trial_id(key: int, brace: str, trial: int) -> str:
    return step_id("trial", brace, trial, key=key)


def trial_of(step_id: str) -> str:
    """The trial a step belongs to, named by its brace-on run's id: a brace-off trial's twin
    (`trial:k03:off:2` -> `trial:k03:on:2`, the ids `trial_id` makes); any other step is its own."""
    parts = step_id.split(":")
    if len(parts) == 4 and parts[0] == "trial" and parts[2] == "off":
        return ":".join((parts[0], parts[1], "on", parts[3]))
    return step_id
