"""``diagnose``: where the disc model parts from the measurement, which unmodelled effect
causes it, and how far the gap shrinks once that effect is modelled — on held-out laps.

1. **Reference model**, the one an engineer has before knowing of any effect: the
   datasheet structure (nominal through-thickness conductivity k_z), one pad-crown
   weighting for every stop, constant friction, a power-law h(V) without a knee and an
   ideal pyrometer. Fitted on the training laps by output error over all four spots:
   h(V) (``a``, ``b``), the constant friction level (braking-power scale) and the mean
   crown weights — the datasheet torque per bar is a nominal figure and uniform pad
   pressure misses the radial heat split of any real disc by tens of °C; without these
   numbers every disc would be "diagnosed" with an effect.
2. **Split**: flying laps alternate between training and held-out (or ``holdout_laps``);
   the out-lap is used by neither. Every "after" figure is measured on held-out laps.
3. **Where**: residuals of the reference model (open loop, all spots) by spot × phase ×
   braking zone × speed band × temperature band, ranked by their share of the squared
   error; a consistency header from the reference model's four-spot UKF first (mean NIS
   per spot against its χ² band, innovation autocorrelation).
4. **Which**: each registered effect fitted alone (jointly with the reference
   parameters) on the training laps, scored on the held-out laps. Effects with a latent
   value per straight (slipstream) get those values on held-out laps from spot 3 only
   (the race sensor), and are scored on the other spots. Ranked by held-out RMSE shrink
   and held-out log-likelihood; the evidence is the residual signature each removes.
5. **Verdict**: the best effect when its shrink is significant — the lower end of a
   95 % bootstrap interval over held-out braking cycles above :data:`MIN_SHRINK_PCT` —
   else ``"none"``. A greedy forward selection gives the combined model; two effects
   whose held-out corrections correlate above :data:`CORRELATED` are flagged.

The package, one module per step: :mod:`.layout` (lap split, zones, straights),
:mod:`.fit` (output-error fits), :mod:`.scores` (held-out scores, consistency),
:mod:`.where`, :mod:`.evidence` (signatures and sizes), :mod:`.four_spot` and
:mod:`.single_spot` (the two diagnoses), :mod:`.sessions` (entry points, pooling,
writers), :mod:`.data_power` (what a session can test) and :mod:`.rig` (the rigs); the
verdict engine is :mod:`brakethermo.diagnosis.verdict`.
"""

from brakethermo.pipelines.diagnose._common import (
    RACE_SPOT,
    DiagnoseOptions,
    DiagnoseResult,
)
from brakethermo.pipelines.diagnose.four_spot import diagnose_session
from brakethermo.pipelines.diagnose.sessions import (
    diagnose,
    diagnose_many,
    pool,
    write_diagnosis,
    write_pooled,
)
from brakethermo.pipelines.estimate import SENSOR_FLOOR_C  # one floor for every command

__all__ = [
    "RACE_SPOT",
    "SENSOR_FLOOR_C",
    "DiagnoseOptions",
    "DiagnoseResult",
    "diagnose",
    "diagnose_many",
    "diagnose_session",
    "pool",
    "write_diagnosis",
    "write_pooled",
]
