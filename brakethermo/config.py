"""Locating and loading the shipped TOML configuration files."""

from __future__ import annotations

import tomllib
from importlib import resources
from pathlib import Path
from typing import Any

from brakethermo.errors import ConfigError


def config_dir() -> Path:
    """Directory of the shipped configuration files.

    In a source checkout or editable install this is ``<repo>/configs``; in a wheel
    the same files are installed as ``brakethermo/_configs``.
    """
    source = Path(__file__).resolve().parents[1] / "configs"
    if source.is_dir():
        return source
    return Path(str(resources.files("brakethermo") / "_configs"))


def load_toml(path: str | Path) -> dict[str, Any]:
    """Read a TOML file, turning every failure into a :class:`ConfigError`."""
    path = Path(path)
    try:
        with path.open("rb") as fh:
            return tomllib.load(fh)
    except FileNotFoundError:
        raise ConfigError("file not found; check the path", path=path) from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"invalid TOML ({exc}); fix the syntax", path=path) from None
    except OSError as exc:
        raise ConfigError(f"cannot read ({exc.strerror})", path=path) from None


def resolve_named(kind: str, name_or_path: str | Path) -> Path:
    """Resolve a config given by shipped name (``cc-340-8``) or by file path.

    Parameters
    ----------
    kind : str
        Sub-directory of :func:`config_dir` (``discs``, ``tracks``, ...).
    name_or_path : str or Path
        A path to a TOML file, or the stem of a shipped file.
    """
    candidate = Path(name_or_path)
    if candidate.suffix == ".toml" or candidate.exists():
        if not candidate.is_file():
            raise ConfigError(f"no such {kind[:-1]} file", path=candidate)
        return candidate
    shipped = config_dir() / kind / f"{name_or_path}.toml"
    if shipped.is_file():
        return shipped
    available = sorted(p.stem for p in (config_dir() / kind).glob("*.toml"))
    raise ConfigError(
        f"unknown {kind[:-1]} '{name_or_path}'; shipped ones are: {', '.join(available) or 'none'},"
        " or give a path to a TOML file"
    )


def require(table: dict[str, Any], key: str, path: Path, kind: type = float) -> Any:
    """Fetch ``table[key]`` converted to ``kind`` or raise a :class:`ConfigError`."""
    if key not in table:
        raise ConfigError(f"missing key '{key}'", path=path)
    try:
        return kind(table[key])
    except (TypeError, ValueError):
        raise ConfigError(
            f"key '{key}' must be {kind.__name__}, got {table[key]!r}", path=path
        ) from None
