"""Alias tables: which file channel names stand for each canonical channel (CHANNELS.md §3).

The shipped table is ``configs/channels.toml``; a user table given with ``--aliases FILE``
has the same shape and is merged over it: its names for a canonical channel are tried
first, then the shipped ones.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path

from brakethermo.config import config_dir, load_toml
from brakethermo.errors import ConfigError
from brakethermo.io.units import CANONICAL_CHANNELS

AliasTable = dict[str, tuple[str, ...]]


def _parse_table(raw: Mapping[str, object], path: Path) -> AliasTable:
    """Validate the ``[aliases]`` table of a parsed TOML document."""
    if set(raw) - {"aliases"}:
        extra = ", ".join(sorted(set(raw) - {"aliases"}))
        raise ConfigError(f"unexpected top-level key(s) {extra}; put names under [aliases]",
                          path=path)
    table = raw.get("aliases")
    if not isinstance(table, dict):
        raise ConfigError("missing table [aliases] (canonical name = [names to try])", path=path)
    parsed: AliasTable = {}
    for canonical, names in table.items():
        if canonical not in CANONICAL_CHANNELS:
            raise ConfigError(
                f"unknown canonical channel '{canonical}' in [aliases]; known channels are: "
                + ", ".join(CANONICAL_CHANNELS),
                path=path,
            )
        if isinstance(names, str):
            names = [names]
        if not isinstance(names, list) or not all(isinstance(n, str) and n for n in names):
            raise ConfigError(
                f"aliases.{canonical} must be a list of non-empty strings, got {names!r}",
                path=path,
            )
        parsed[canonical] = tuple(dict.fromkeys(names))
    return parsed


def default_aliases() -> AliasTable:
    """The shipped alias table, every canonical channel trying at least its own name."""
    path = config_dir() / "channels.toml"
    table = _parse_table(load_toml(path), path)
    return {c: tuple(dict.fromkeys((*table.get(c, ()), c))) for c in CANONICAL_CHANNELS}


def load_aliases(user_file: str | Path | None = None) -> AliasTable:
    """The alias table to use: the shipped one, with ``user_file`` merged over it.

    Parameters
    ----------
    user_file : str or Path, optional
        A TOML file with an ``[aliases]`` table; its names are tried before the shipped ones.

    Raises
    ------
    ConfigError
        Missing file, invalid TOML, or a table of the wrong shape.
    """
    table = default_aliases()
    if user_file is None:
        return table
    path = Path(user_file)
    user = _parse_table(load_toml(path), path)
    for canonical, names in user.items():
        table[canonical] = tuple(dict.fromkeys((*names, *table[canonical])))
    return table


def resolve(table: AliasTable, available: Iterable[str]) -> dict[str, str]:
    """Map canonical names to the file's channel names.

    For each canonical channel the first alias present in ``available`` wins; an exact
    match is preferred over a case-insensitive one.

    Returns
    -------
    dict of str to str
        Canonical name -> source name, for the canonical channels found.
    """
    names = list(available)
    exact = set(names)
    folded: dict[str, str] = {}
    for name in names:
        folded.setdefault(name.casefold(), name)
    found: dict[str, str] = {}
    for canonical, aliases in table.items():
        for alias in aliases:
            if alias in exact:
                found[canonical] = alias
                break
        else:
            for alias in aliases:
                if alias.casefold() in folded:
                    found[canonical] = folded[alias.casefold()]
                    break
    return found
