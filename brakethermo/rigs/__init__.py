"""Rig physics as pure functions (no files, no filters), one concept per module.

Roller rig: :mod:`hertz` (normal contact), :mod:`kalker` (Kalker's creep coefficients),
:mod:`polach` (Polach's creep-force law and slip-velocity friction), :mod:`fastsim`
(Kalker's FASTSIM), :mod:`motor` (induction motor under V/f control), :mod:`roller_rig`
(the rig's datasheet). Electric brake booster: :mod:`booster` (hydraulics, reaction
disk, leverage) and :mod:`booster_datasheet`. Electro-mechanical caliper: :mod:`emb`
(clamp-force models, eq. 6-8 of Saric & Bab-Hadiashar). Tyre: :mod:`tyre` (μ-slip curves).
"""
