"""Alias tables: which file channel names stand for each canonical channel (CHANNELS.md §3).

The shipped table is ``configs/channels.toml``; a user table given with ``--aliases FILE``
has the same shape and is merged over it: its names for a canonical channel are tried
first, then the shipped ones.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path

from brakethermo.config import ConfigTable, config_dir, load_toml
from brakethermo.io.units import CANONICAL_CHANNELS

AliasTable = dict[str, tuple[str, ...]]


def _parse_table(raw: Mapping[str, object], path: Path) -> AliasTable:
    """Validate the ``[aliases]`` table of a parsed TOML document (config schema layer)."""
    top = ConfigTable(dict(raw), path)
    top.only(("aliases",))
    table = top.table("aliases")
    table.only(CANONICAL_CHANNELS, "a canonical channel name")
    return {canonical: tuple(dict.fromkeys(table.strings(canonical))) for canonical in table.raw}


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
