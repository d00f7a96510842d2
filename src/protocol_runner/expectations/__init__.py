"""Expectations declared in a protocol (`expectations:`), their metric library and one generic evaluator.

`spec` is the schema of one declared expectation, `metrics` the documented metric library (per-trial
values of one configuration), `evaluate` the decision rule that turns a declaration and an archive's
data into a verdict: met, not met or not evaluable, with the numbers behind it (docs/protocol.md).
"""
