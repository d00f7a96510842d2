"""Pure numpy/scipy processing of recorded trials (thesis §3, §5.7, §6.1); see docs/analysis.md.

transition -> filters -> (scaling, at acquisition) -> branches/subtraction -> centring, cycles, energy,
element_fit; `pipeline.process_configuration` runs them for one configuration.
"""
