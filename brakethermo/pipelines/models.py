"""Resolving the disc datasheet and the h(V) law a session is processed with."""

from __future__ import annotations

from pathlib import Path

from brakethermo.config import config_dir
from brakethermo.errors import ConfigError
from brakethermo.io.session import Session
from brakethermo.thermal.disc import DiscSpec, load_disc
from brakethermo.thermal.hlaw import HLawRecord, read_h_law

DEFAULT_DISC = "cc-340-8"


def disc_for(session: Session, disc: str | Path | None = None) -> DiscSpec:
    """The datasheet given by the user, else the session's ``disc`` fact, else the default."""
    return load_disc(disc or session.metadata.get("disc") or DEFAULT_DISC)


def shipped_h_law(disc: DiscSpec) -> Path | None:
    """The h law shipped for this disc (identified from the sample test session), if any."""
    path = config_dir() / "hlaw" / f"{disc.id}.toml"
    return path if path.is_file() else None


def h_law_for(disc: DiscSpec, h_law: str | Path | None) -> tuple[HLawRecord, Path]:
    """Read the user's h law file, or the one shipped for the disc."""
    path = Path(h_law) if h_law is not None else shipped_h_law(disc)
    if path is None:
        raise ConfigError(
            f"no h(V) law for disc '{disc.id}': run `brakethermo identify-h` on a multi-spot"
            " test session and pass its h_law.toml with --h-law"
        )
    return read_h_law(path), path
