"""Names the simulator and the estimator share, and nothing else: they are two programs
that agree on the words of the session contract, not on physics."""

from __future__ import annotations

# The unmodelled effects of OUTPUTS.md (``diagnose``): fixed names, in this order.
EFFECT_NAMES = (
    "power_distribution",
    "h_speed_knee",
    "slipstream",
    "friction_temperature",
    "thickness_gradient",
    "sensor_lag",
    "emissivity_error",
)
