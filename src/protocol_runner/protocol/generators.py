"""Matrix generators: a set's configurations written as a rule instead of rows (docs/protocol.md).

- `full_factorial`: the cross product of the listed factors' levels (the last factor varies fastest),
  each combination with the `fixed` levels;
- `one_factor_at_a_time`: the baseline, then each `vary` factor at each of its listed levels in turn, the
  other factors at the baseline.

Generated configurations are appended to their set's explicit rows. Their keys and test-run numbers
continue after the largest key and run of the protocol's explicit rows, in generation order (sets in file
order), so the same file always gives the same matrix. A generator's trajectory is `trajectory` or, per
level of one factor, `trajectory_by_level`.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator

from .loaded import Loc, Problem
from .schema import (
    ConfigurationSpec,
    FullFactorialSpec,
    OneFactorAtATimeSpec,
    Protocol,
    SetSpec,
    _GeneratorSpec,
)


def expand_generators(p: Protocol) -> tuple[Protocol, list[Problem], dict[Loc, Loc]]:
    """The protocol with every set's generated configurations appended; problems in the generators;
    generated row location -> its generator's location (for line numbers)."""
    explicit = [c for s in p.sets for c in s.configurations]
    next_key = max((c.key for c in explicit), default=0) + 1
    next_run = max((c.run for c in explicit), default=0) + 1
    problems: list[Problem] = []
    origins: dict[Loc, Loc] = {}
    count_so_far = len(explicit)
    if count_so_far > MAX_CONFIGURATIONS:
        too_many = (
            f"{count_so_far:,} configurations, more than the {MAX_CONFIGURATIONS:,} a protocol may have"
        )
        return p, [(("sets",), too_many)], origins
    sets: list[SetSpec] = []
    for i, s in enumerate(p.sets):
        rows: list[ConfigurationSpec] = list(s.configurations)
        for kind, gen in (
            ("full_factorial", s.full_factorial),
            ("one_factor_at_a_time", s.one_factor_at_a_time),
        ):
            if gen is None:
                continue
            loc: Loc = ("sets", i, kind)
            found = list(_check_generator(p, gen, loc))
            if found:
                problems += found
                continue
            count = _count(p, gen)
            if count_so_far + count > MAX_CONFIGURATIONS:
                problems.append(
                    (
                        loc,
                        f"this generator makes {count:,} configurations, {count_so_far + count:,} in all with "
                        f"those before it: more than the {MAX_CONFIGURATIONS:,} a protocol may have (list "
                        "fewer levels, or split the campaign)",
                    )
                )
                continue
            count_so_far += count
            levels = _full_factorial(p, gen) if isinstance(gen, FullFactorialSpec) else _ofat(gen)
            for combo in levels:
                origins[("sets", i, "configurations", len(rows))] = loc
                row = {"key": next_key, "run": next_run, "trajectory": _trajectory(gen, combo)}
                rows.append(
                    ConfigurationSpec.model_validate(
                        {**row, "trials": gen.trials, "description": gen.description, **combo}
                    )
                )
                next_key += 1
                next_run += 1
        sets.append(s.model_copy(update={"configurations": rows}))
    return p.model_copy(update={"sets": sets}), problems, origins


MAX_CONFIGURATIONS = 10_000
"""The most configurations a protocol may have once its generators are expanded: at 50 trials each, half a
million trials, years of robot time. The count is worked out before anything is expanded, so a generator
of millions of combinations is refused without the memory or the time it would take."""


def _count(p: Protocol, gen: _GeneratorSpec) -> int:
    """How many configurations a (checked) generator makes, without making them."""
    if isinstance(gen, FullFactorialSpec):
        return math.prod(len(_levels(p, f, choice)) for f, choice in gen.factors.items())
    assert isinstance(gen, OneFactorAtATimeSpec)
    return sum(1 for _ in _ofat(gen))


def _levels(p: Protocol, factor: str, choice: list[str] | str) -> list[str]:
    return list(p.factors[factor]) if choice == "all" else list(choice)


def _full_factorial(p: Protocol, gen: FullFactorialSpec) -> Iterator[dict[str, str]]:
    names = list(gen.factors)
    lists = [_levels(p, f, gen.factors[f]) for f in names]
    for combo in itertools.product(*lists):
        yield {**dict(gen.fixed), **dict(zip(names, combo, strict=True))}


def _ofat(gen: OneFactorAtATimeSpec) -> Iterator[dict[str, str]]:
    if gen.include_baseline:
        yield dict(gen.baseline)
    for factor, levels in gen.vary.items():
        for level in levels:
            if level != gen.baseline.get(factor):
                yield {**dict(gen.baseline), factor: level}


def _trajectory(gen: _GeneratorSpec, combo: dict[str, str]) -> str:
    if gen.trajectory is not None:
        return gen.trajectory
    assert gen.trajectory_by_level is not None
    return gen.trajectory_by_level.levels[combo[gen.trajectory_by_level.factor]]


def _check_generator(p: Protocol, gen: _GeneratorSpec, loc: Loc) -> Iterator[Problem]:
    named: dict[str, list[tuple[Loc, str]]] = {}
    if isinstance(gen, FullFactorialSpec):
        for f, choice in gen.factors.items():
            if isinstance(choice, list):
                named[f] = [((*loc, "factors", f, j), lv) for j, lv in enumerate(choice)]
            else:
                named.setdefault(f, [])
        for f, lv in gen.fixed.items():
            if f in gen.factors:
                yield (*loc, "fixed", f), f"factor {f!r} is both varied (`factors`) and fixed"
            named.setdefault(f, []).append(((*loc, "fixed", f), lv))
    elif isinstance(gen, OneFactorAtATimeSpec):
        for f, lv in gen.baseline.items():
            named.setdefault(f, []).append(((*loc, "baseline", f), lv))
        for f, levels in gen.vary.items():
            if f not in gen.baseline:
                yield (*loc, "vary", f), f"factor {f!r} is varied but has no baseline level"
            named.setdefault(f, []).extend(((*loc, "vary", f, j), lv) for j, lv in enumerate(levels))
    for f, items in named.items():
        if f not in p.factors:
            where = items[0][0][: len(loc) + 2] if items else (*loc, "factors", f)  # `all` of a factorial
            yield where, f"unknown factor {f!r} (declared: {', '.join(p.factors) or 'none'})"
            continue
        for where, lv in items:
            if lv not in p.factors[f]:
                yield where, f"unknown level {lv!r} of {f} (known: {', '.join(p.factors[f])})"
    known = ", ".join(p.trajectories)
    if gen.trajectory is not None and gen.trajectory not in p.trajectories:
        yield (*loc, "trajectory"), f"unknown trajectory {gen.trajectory!r} (known: {known})"
    by = gen.trajectory_by_level
    if by is not None:
        tloc: Loc = (*loc, "trajectory_by_level")
        for lv, name in by.levels.items():
            if name not in p.trajectories:
                yield (*tloc, "levels", lv), f"unknown trajectory {name!r} (known: {known})"
        varied = set(gen.baseline) if isinstance(gen, OneFactorAtATimeSpec) else set(named)
        if by.factor not in varied:
            yield (*tloc, "factor"), f"{by.factor!r} is not one of this generator's factors"
        elif (
            by.factor in p.factors
        ):  # the levels it uses (`all`: every level); an unknown one is reported above
            used = dict.fromkeys(lv for _, lv in named[by.factor]) or p.factors[by.factor]
            for lv in used:
                if lv not in by.levels and lv in p.factors[by.factor]:
                    yield (*tloc, "levels"), f"no trajectory for level {lv!r} of {by.factor}"
