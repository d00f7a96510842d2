"""Calibration-check limits (archived as JSON) written as a readable sentence for the report."""

from __future__ import annotations

import json

_PHRASES: dict[str, str] = {
    "max_settle_error_deg": "settle error ≤ {v} deg",
    "settle_error_deg": "settle error ≤ {v} deg",
    "max_drift_deg": "drift within the set ≤ {v} deg",
    "max_time_constant_change_s": "time-constant change within the set ≤ {v} s",
}


def _number(value: object) -> str:
    return f"{value:g}" if isinstance(value, int | float) and not isinstance(value, bool) else str(value)


def limits_text(raw: str) -> str:
    """E.g. `{"max_settle_error_deg": 3.0, "time_constant_s": [0.1, 0.35]}` ->
    "settle error ≤ 3 deg; time constant 0.1-0.35 s". Text that is not a JSON object is returned as is."""
    try:
        limits = json.loads(raw) if raw else {}
    except ValueError:
        return raw
    if not isinstance(limits, dict):
        return raw
    parts: list[str] = []
    for name, value in limits.items():
        if name == "time_constant_s" and isinstance(value, list) and len(value) == 2:
            parts.append(f"time constant {_number(value[0])}-{_number(value[1])} s")
        elif name in _PHRASES:
            parts.append(_PHRASES[name].format(v=_number(value)))
        else:
            parts.append(f"{name.replace('_', ' ')} {_number(value)}")
    return "; ".join(parts) if parts else "none recorded"
