"""What the protocol cites for each part of the report (`report.citations`, docs/protocol.md "Report").

A campaign that reproduces a source (the knee reproduces the 2007 thesis) names, per report part, where
the source shows the same thing ("thesis Figures 41-46"); the report prints it beside that part. Nothing
is cited unless the protocol says so: an ankle or elbow report shows no knee-thesis figure numbers."""

from __future__ import annotations

import yaml

from protocol_runner.report.declared import protocol_document

#: The report parts a protocol can cite, as `report.citations` keys (protocol.schema.CitationsSpec).
PARTS: tuple[str, ...] = (
    "configurations",
    "comparisons",
    "energy",
    "reference",
    "models",
    "elements",
    "bouc_wen",
    "matrix",
    "calibration",
)


def declared_citations(protocol_text: str) -> dict[str, str]:
    """Every part of `PARTS` mapped to the protocol's citation text for it ("" when none is declared).

    The protocol was validated when it ran; an unreadable or older text cites nothing."""
    out = dict.fromkeys(PARTS, "")
    try:
        doc = protocol_document(protocol_text)
    except yaml.YAMLError:
        return out
    report = doc.get("report") if isinstance(doc, dict) else None
    declared = report.get("citations") if isinstance(report, dict) else None
    if isinstance(declared, dict):
        for part in PARTS:
            text = declared.get(part)
            if isinstance(text, str):
                out[part] = text.strip()
    return out
