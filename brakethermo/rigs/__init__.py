"""Rig physics as pure functions: contact mechanics, electric drives (no files, no filters).

One concept per module: :mod:`hertz` (normal contact), :mod:`kalker` (Kalker's creep
coefficients), :mod:`polach` (Polach's creep-force law and slip-velocity friction),
:mod:`fastsim` (Kalker's FASTSIM), :mod:`motor` (induction motor under V/f control);
:mod:`roller_rig` holds the roller rig's datasheet.
"""
