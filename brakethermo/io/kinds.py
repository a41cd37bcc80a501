"""Which kind of session a set of channels makes: a track session or one of the rigs.

A user who hands the roller-rig command a clamp-force log should hear which command reads
it, not only which channel is missing; ``diagnose`` recognises a rig session the same way.
The channel names are the canonical ones of CHANNELS.md.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class SessionKind:
    """One kind of session of the data contract.

    Parameters
    ----------
    words : str — the kind in a sentence ("an EMB caliper rig").
    marks : tuple of str — channels that, all present, mark a session as this kind.
    contract : tuple of str — every channel of its contract (CHANNELS.md).
    command : str — what reads it.
    """

    words: str
    marks: tuple[str, ...]
    contract: tuple[str, ...]
    command: str

    @property
    def table(self) -> str:
        """The parquet a rig's command writes in ``OUT/<stem>/`` (``clamp_force``, ...)."""
        return self.command.split()[-1].replace("-", "_")


KINDS: dict[str, SessionKind] = {
    "ebooster": SessionKind(
        "an E-Booster rig", ("pushrod_displacement", "reaction_disk_delta"),
        ("pushrod_displacement", "reaction_disk_delta", "master_cylinder_pressure",
         "front_circuit_pressure", "rear_circuit_pressure", "pedal_force"),
        "brakethermo ebooster"),
    "emb": SessionKind(
        "an EMB caliper rig", ("motor_angle", "motor_current"),
        ("motor_angle", "motor_current", "clamp_force"), "brakethermo clamp-force"),
    "roller-rig": SessionKind(
        "a roller rig", ("wheel_omega", "roller_omega"),
        ("wheel_omega", "roller_omega", "wheel_torque", "normal_force", "roller_torque",
         "rolling_radius_ref"), "brakethermo roller-rig"),
    "mu-slip": SessionKind(
        "a tyre (mu-slip) rig", ("drag_force", "wheel_speed"),
        ("vehicle_speed", "wheel_speed", "drag_force", "normal_force", "slip_ratio",
         "friction_coefficient"),
        "brakethermo mu-slip"),
    "disc": SessionKind(
        "a track (disc temperature)", ("disc_temp",),
        ("speed", "wheel_speed_front", "brake_pressure_front", "disc_temp", "disc_temp_spot1",
         "disc_temp_spot2", "disc_temp_spot3", "disc_temp_spot4", "ambient_temp", "distance",
         "lap_beacon"),
        "brakethermo estimate, identify-h or diagnose"),
}
# a rig as diagnose names it (diagnosis.json "rig"), where that is not its kind's name
DIAGNOSIS_RIGS = {"tyre": "mu-slip"}


def rig_kind(name: str) -> SessionKind | None:
    """The rig kind of a name as :data:`KINDS` or diagnose gives it (None: no rig)."""
    kind = DIAGNOSIS_RIGS.get(name, name)
    return KINDS[kind] if kind in KINDS and kind != "disc" else None


RIG_MARKS = tuple(c for k, kind in KINDS.items() if k != "disc" for c in kind.marks)


def session_kind(channels: Iterable[str]) -> str | None:
    """``"disc"``, a rig's name, or ``None`` when the canonical ``channels`` mark none."""
    have = set(channels)
    if any(c.startswith("disc_temp") for c in have):
        return "disc"
    return next((k for k, kind in KINDS.items() if all(m in have for m in kind.marks)), None)


def kind_hint(channels: Iterable[str], missing: str) -> str:
    """A sentence naming the command that reads a session which lacks ``missing`` because
    it is of another kind; ``""`` when its channels mark no kind or the kind that has it."""
    kind = session_kind(channels)
    if kind is None or missing in KINDS[kind].contract:
        return ""
    k = KINDS[kind]
    return f" Its channels are those of {k.words} session: {k.command} reads it."


def detect_rig(path: str | Path, aliases: str | Path | None = None) -> str | None:
    """The rig a session file comes from, from its channels (None: a disc session, or a
    file that cannot be read)."""
    from brakethermo.errors import BrakethermoError
    from brakethermo.io.load import load_session

    try:
        s = load_session(path, rate_hz=None, aliases=aliases, channels=RIG_MARKS)
    except BrakethermoError:
        return None
    kind = session_kind({*s.available, *s.channels})
    return None if kind == "disc" else kind
