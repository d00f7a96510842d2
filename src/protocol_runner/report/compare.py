"""Two sessions side by side (`--compare`, docs/report.md "Session comparison"): configurations matched
on their declared settings (trajectory and level labels, not keys), energy per cycle and range reached B
minus A per joint on trial values, each quantity decided at the Bonferroni level `ALPHA_EACH`.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

from protocol_runner.analysis.statistics import WelchInterval, welch_interval
from protocol_runner.errors import InvalidInput
from protocol_runner.report.figures import overlay_figure
from protocol_runner.report.headline import configuration_stats, trial_values
from protocol_runner.report.load import load_report_data
from protocol_runner.report.model import Configuration, ReportData
from protocol_runner.report.render import checked_output, template_environment, write_atomically

TEMPLATE = "compare.html.j2"

#: The two compared quantities and the per-quantity significance level (Bonferroni: 0.05 / 2).
QUANTITIES = ("energy per cycle", "range reached")
ALPHA_EACH = 0.05 / len(QUANTITIES)

#: A pair's `joint` when it compares all the joints of a configuration together (their total energy).
TOTAL = "total"


@dataclass(frozen=True)
class Pair:
    """One joint of a configuration of A matched with the same joint of one of B, and their differences
    (B minus A); with `joint` TOTAL, all the joints together (`a` and `b` are then the first joint's part,
    for the configuration's key and settings, and `range` is undefined)."""

    a: Configuration
    b: Configuration
    energy: WelchInterval
    range: WelchInterval
    changed: tuple[tuple[str, str, str], ...]  # (setting, value in A, value in B) where they differ
    joint: str = ""

    @property
    def total(self) -> bool:
        """True when the pair compares all the joints of its configurations together."""
        return self.joint == TOTAL

    @property
    def energy_differs(self) -> bool:
        """The energy per cycle differs (p < `ALPHA_EACH`; an undefined p-value: no)."""
        return bool(self.energy.p_value < ALPHA_EACH)

    @property
    def range_differs(self) -> bool:
        """The range reached differs (p < `ALPHA_EACH`)."""
        return bool(self.range.p_value < ALPHA_EACH)

    @property
    def significant(self) -> bool:
        """True when either quantity differs."""
        return self.energy_differs or self.range_differs

    @property
    def verdict(self) -> str:
        """Which quantities differ: "energy per cycle", "range reached", both joined by "and", or "none"."""
        flags = (self.energy_differs, self.range_differs)
        return " and ".join(q for q, f in zip(QUANTITIES, flags, strict=True) if f) or "none"

    @property
    def label(self) -> str:
        """Human label of the shared settings."""
        levels = ", ".join(f"{k} {v}" for k, v in self.a.settings.levels())
        return levels or self.a.settings.trajectory or self.a.profile


@dataclass(frozen=True)
class SessionComparison:
    """The matched pairs of two archives and the configurations left unmatched on each side."""

    a: ReportData
    b: ReportData
    pairs: tuple[Pair, ...]

    @property
    def only_a(self) -> tuple[int, ...]:
        """Keys of A's configurations that no configuration of B matches, in key order."""
        return _unmatched(self.a, {p.a.key for p in self.pairs})

    @property
    def only_b(self) -> tuple[int, ...]:
        """Keys of B's configurations that no configuration of A matches, in key order."""
        return _unmatched(self.b, {p.b.key for p in self.pairs})

    @property
    def n_configurations(self) -> int:
        """Matched pairs of configurations (each compared per joint, and in total for several joints)."""
        return len({(p.a.key, p.b.key) for p in self.pairs})

    @property
    def n_significant(self) -> int:
        """Pairs (per joint, and totals) that differ significantly in energy per cycle or range reached."""
        return sum(p.significant for p in self.pairs)

    def table(self) -> str:
        """The printed table: one line per matched pair and joint (and total)."""
        width = max([5, *(len(p.joint) for p in self.pairs)])
        head = (
            f"{'A':>4} {'B':>4}  {'joint':<{width}}  {'energy B-A (J)':>15} {'95 % interval':>20} {'p':>6}  "
            f"{'range B-A (deg)':>15} {'95 % interval':>20} {'p':>6}  differs in"
        )
        lines = [head]
        for p in self.pairs:
            lines.append(
                f"{p.a.key:>4} {p.b.key:>4}  {p.joint:<{width}}  {_num(p.energy.difference):>15} "
                f"{_ival(p.energy):>20} {_p(p.energy):>6}  {_num(p.range.difference):>15} "
                f"{'—' if p.total else _ival(p.range):>20} "
                f"{_p(p.range):>6}  {p.verdict}"
            )
        n = self.n_configurations
        per_joint = (
            ""
            if len(self.pairs) == n
            else f" ({len(self.pairs)} comparisons: per joint, and all joints together)"
        )
        lines.append(
            f"{n} matched configurations{per_joint}, {self.n_significant} differ in energy per cycle or "
            f"range reached (each at p < {ALPHA_EACH:g}); "
            f"unmatched: A {list(self.only_a) or 'none'}, B {list(self.only_b) or 'none'}"
        )
        return "\n".join(lines)


def _unmatched(data: ReportData, matched: set[int]) -> tuple[int, ...]:
    return tuple(sorted(k for k in data.keys if k not in matched))


def _num(value: float) -> str:
    return f"{value:+.3f}" if math.isfinite(value) else "—"


def _p(w: WelchInterval) -> str:
    return f"{w.p_value:.3f}" if math.isfinite(w.p_value) else "—"


def _ival(w: WelchInterval) -> str:
    if not (math.isfinite(w.low) and math.isfinite(w.high)):
        return "— (too few trials)"
    return f"[{w.low:+.3f}, {w.high:+.3f}]"


def signature(cfg: Configuration) -> tuple[tuple[str, str], ...]:
    """The settings a match is made on: the trajectory and each declared factor's level label."""
    items = [("trajectory", cfg.settings.trajectory or cfg.profile)]
    items.extend(cfg.settings.levels())
    return tuple(sorted(items))


def _physical(cfg: Configuration) -> dict[str, object]:
    """What a pair's "changed settings" compares: factor quantities, device parameters and the
    trajectory's fields as the plan resolved them (`trajectory.range_deg`, `trajectory.periods`, ...; of a
    multi-joint motion `trajectory.<joint>.<field>`), its name aside (the match is made on it)."""
    out: dict[str, object] = {k: v for k, v in cfg.settings.flat().items() if "." in k}
    for element in cfg.settings.device:
        for name, value in element.params:
            out[f"device.{element.name}.{name}"] = value
    out.update(_trajectory_fields(cfg.trajectory_json))
    return out


def _trajectory_fields(text: str) -> dict[str, object]:
    """`trajectory.<field>` -> value of a trial's trajectory JSON (numbers and lists of numbers as floats
    and tuples); empty when there is none or it cannot be read (an archive predating the attribute)."""
    try:
        doc = json.loads(text) if text else {}
    except ValueError:
        return {}
    if not isinstance(doc, dict):
        return {}
    single = "profile" in doc
    out: dict[str, object] = {}
    for joint, fields in [("", doc)] if single else list(doc.items()):
        if not isinstance(fields, dict):
            continue
        prefix = f"trajectory.{joint}." if joint else "trajectory."
        for name, value in fields.items():
            if name != "name":
                out[prefix + name] = _plain(value)
    return out


def _plain(value: object) -> object:
    if isinstance(value, bool) or value is None:
        return str(value)
    if isinstance(value, int | float):
        return float(value)
    if isinstance(value, list) and all(isinstance(v, int | float) and not isinstance(v, bool) for v in value):
        return tuple(float(v) for v in value)
    return value if isinstance(value, str) else json.dumps(value)


def _changed(a: Configuration, b: Configuration) -> tuple[tuple[str, str, str], ...]:
    pa, pb = _physical(a), _physical(b)
    names = sorted(set(pa) | set(pb))
    return tuple((n, _text(pa.get(n)), _text(pb.get(n))) for n in names if pa.get(n) != pb.get(n))


def _text(value: object) -> str:
    if value is None:
        return "—"
    if isinstance(value, tuple):
        return "[" + ", ".join(f"{v:g}" for v in value) + "]"
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def _firsts(data: ReportData) -> list[Configuration]:
    """Each configuration once (its first joint's part: the settings are the configuration's), in key order."""
    return sorted((c for c in map(data.configuration, data.keys) if c is not None), key=lambda c: c.key)


def match(a: ReportData, b: ReportData) -> tuple[tuple[Configuration, Configuration], ...]:
    """Pairs (A, B) of configurations (each its first joint's part) with equal signatures (several identical
    ones pair in key order); the configurations left over are `SessionComparison.only_a` / `only_b`."""
    groups_b: dict[tuple[tuple[str, str], ...], list[Configuration]] = {}
    for cfg in _firsts(b):
        groups_b.setdefault(signature(cfg), []).append(cfg)
    pairs = []
    for cfg in _firsts(a):
        candidates = groups_b.get(signature(cfg))
        if candidates:
            same_key = next((c for c in candidates if c.key == cfg.key), candidates[0])
            candidates.remove(same_key)
            pairs.append((cfg, same_key))
    return tuple(pairs)


def compare_data(a: ReportData, b: ReportData) -> SessionComparison:
    """Match and compare two loaded archives; `InvalidInput` when no configuration matches."""
    matched = match(a, b)
    if not matched:
        raise InvalidInput(
            f"{a.session.archive_path} and {b.session.archive_path} have no configuration with the same "
            "settings (trajectory and level labels): nothing to compare"
        )
    pairs: list[Pair] = []
    for ca, cb in matched:
        changed = _changed(ca, cb)
        joints_b = {c.joint: c for c in b.joint_configurations(cb.key)}
        for ja in a.joint_configurations(ca.key):
            jb = joints_b.get(ja.joint)
            if jb is not None:
                energy, reach = (
                    welch_interval(trial_values(ja, m), trial_values(jb, m))
                    for m in ("energy_per_cycle", "range_reached")
                )
                pairs.append(Pair(ja, jb, energy, reach, changed, ja.joint))
        ta, tb = a.total(ca.key), b.total(cb.key)
        several = len(a.joint_configurations(ca.key)) > 1 and len(b.joint_configurations(cb.key)) > 1
        if several and ta is not None and tb is not None:
            ea, eb = configuration_stats(ca, ta).trial_energy_j, configuration_stats(cb, tb).trial_energy_j
            pairs.append(Pair(ca, cb, welch_interval(ea, eb), welch_interval((), ()), changed, TOTAL))
    return SessionComparison(a, b, tuple(pairs))


def compare_archives(a: Path, b: Path) -> SessionComparison:
    """Load two archives (files or session directories) and compare them."""
    return compare_data(load_report_data(Path(a), workers=1), load_report_data(Path(b), workers=1))


def render_comparison(result: SessionComparison, output: Path) -> Path:
    """Write the comparison page (self-contained HTML, overlaid loops inline) to `output`."""
    output = checked_output(output, "Comparison", "compare.html")
    env = template_environment()
    figures = {
        (p.a.key, p.b.key, p.joint): None if p.total else overlay_figure(p.a, p.b) for p in result.pairs
    }
    # the template's number formats and the per-quantity significance level
    helpers = {"fmt": _num, "ival": _ival, "pval": _p, "alpha": ALPHA_EACH}
    html = env.get_template(TEMPLATE).render(
        result=result, figure_of=lambda p: figures[(p.a.key, p.b.key, p.joint)], **helpers
    )
    write_atomically(output, html)
    return output
