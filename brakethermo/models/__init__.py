"""State-space models for the filters, and the effects that extend them.

Between the physics (:mod:`brakethermo.thermal` for the disc, pure functions that know
no files) and the pipelines: a model here turns physics into what the filter engine of
:mod:`brakethermo.estimation` runs — a batched transition ``f(X, k)``, process noise,
a measurement — for the disc (with its registered effects) and for each rig.
"""
