"""Locating, loading and validating the TOML configuration files.

Every TOML file the tool reads (tuning, h law, aliases, disc datasheets, simulator
tracks) goes through :func:`load_toml` and then :class:`ConfigTable`, the one schema
layer: each value is fetched with the type and range it must have, so that every field
of every file fails the same way — one :class:`ConfigError` naming the file, the key,
what was expected and what was found.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Iterable, Mapping, Sequence
from importlib import resources
from pathlib import Path
from typing import Any

from brakethermo.errors import ConfigError

MAX_CONFIG_BYTES = 4 << 20  # no configuration of this tool comes near; a log file does
_MISSING: Any = object()


def config_dir() -> Path:
    """Directory of the shipped configuration files.

    In a source checkout or editable install this is ``<repo>/configs``; in a wheel
    the same files are installed as ``brakethermo/_configs``.
    """
    source = Path(__file__).resolve().parents[1] / "configs"
    if source.is_dir():
        return source
    return Path(str(resources.files("brakethermo") / "_configs"))


def _decode(data: bytes, path: Path) -> str:
    """The text of a TOML file, or a message that says how to save it."""
    if data.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise ConfigError("is UTF-16 text; save it as UTF-8 (TOML files are UTF-8)", path=path)
    if b"\x00" in data[:8192]:
        raise ConfigError("is a binary file, not TOML text; give the .toml file", path=path)
    try:
        return data.decode("utf-8-sig")  # a BOM (Windows editors) is harmless
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        raise ConfigError(
            f"is not UTF-8 text (byte 0x{data[exc.start]:02x} on line {line}); save it as"
            " UTF-8 (TOML files are UTF-8)",
            path=path,
        ) from None


def load_toml(path: str | Path) -> dict[str, Any]:
    """Read a TOML file, turning every failure into a :class:`ConfigError`."""
    path = Path(path)
    try:
        if path.is_dir():
            raise ConfigError("is a folder; give the path of a .toml file", path=path)
        with path.open("rb") as fh:
            data = fh.read(MAX_CONFIG_BYTES + 1)
    except FileNotFoundError:
        raise ConfigError("file not found; check the path", path=path) from None
    except OSError as exc:
        raise ConfigError(f"cannot read ({exc.strerror})", path=path) from None
    if len(data) > MAX_CONFIG_BYTES:
        raise ConfigError(
            f"is larger than {MAX_CONFIG_BYTES >> 20} MiB, not a configuration file", path=path
        )
    try:
        return tomllib.loads(_decode(data, path))
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"invalid TOML ({exc}); fix the syntax", path=path) from None


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


# The tables that mark each rig's datasheet (configs/rigs/), to name a datasheet given to
# the wrong command instead of reporting its first missing key.
RIG_DATASHEET_TABLES = {"ebooster": ("master_cylinder", "reaction_disk"),
                        "roller-rig": ("wheel", "roller")}


def require_rig_datasheet(raw: Mapping[str, Any], rig: str, path: Path) -> None:
    """Refuse a datasheet that is another rig's (or none), naming whose it is.

    Raises
    ------
    ConfigError
        ``raw`` lacks the tables of ``rig``'s datasheet (:data:`RIG_DATASHEET_TABLES`).
    """
    if all(t in raw for t in RIG_DATASHEET_TABLES[rig]):
        return
    other = next((r for r, tables in RIG_DATASHEET_TABLES.items()
                  if r != rig and all(t in raw for t in tables)), None)
    names = {"ebooster": "an E-Booster bench", "roller-rig": "a roller rig"}
    whose = f"{names[other]}'s datasheet" if other else "no rig datasheet we know"
    raise ConfigError(f"is {whose}, not {names[rig]}'s (it lacks the tables"
                      f" {', '.join(f'[{t}]' for t in RIG_DATASHEET_TABLES[rig])}); give"
                      f" {names[rig]}'s datasheet, e.g. the shipped '{rig}'", path=path)


def describe(value: Any) -> str:
    """How a TOML value reads in an error message ("found ...")."""
    if value is _MISSING:
        return "nothing (the key is missing)"
    if isinstance(value, dict):
        return "a table"
    if isinstance(value, list | tuple):
        if not value:
            return "an empty list"
        if len(value) <= 4 and all(isinstance(v, int | float) for v in value):
            return "[" + ", ".join(describe(v) for v in value) + "]"
        return f"a list of {len(value)}"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else str(value)
    if isinstance(value, str):
        shown = value if len(value) <= 40 else value[:37] + "..."
        return f"the text {shown!r}"
    return repr(value)


def _range(lo: float, hi: float) -> str:
    if math.isinf(lo) and math.isinf(hi):
        return ""
    if math.isinf(hi):
        return f" >= {lo:g}"
    if math.isinf(lo):
        return f" <= {hi:g}"
    return f" between {lo:g} and {hi:g}"


class _Found(str):
    """A "found" text already worded (not a TOML value to describe)."""


def found(text: str) -> str:
    """Word the "found" part of :meth:`ConfigTable.error` directly."""
    return _Found(text)


class ConfigTable:
    """One table of a TOML file under validation: typed values by key.

    Parameters
    ----------
    raw : mapping
        The parsed table.
    path : Path
        The file, for messages.
    where : str
        Dotted key of this table in the file (``""`` for the top level).

    Every accessor raises :class:`ConfigError` with the same shape of message:
    ``<file>: key '<dotted key>': expected <what>, found <value>``.
    """

    def __init__(self, raw: Any, path: str | Path, where: str = ""):
        self.path = Path(path)
        self.where = where
        if not isinstance(raw, dict):
            raise self.error("", "a table", raw)
        self.raw: dict[str, Any] = raw

    # ------------------------------------------------------------------ plumbing
    def key(self, key: str) -> str:
        """Dotted name of ``key`` in the file."""
        return f"{self.where}.{key}" if self.where and key else (self.where or key)

    def error(self, key: str, expected: str, found: Any) -> ConfigError:
        """The one message of the schema layer."""
        found_text = found if isinstance(found, _Found) else describe(found)
        name = self.key(key)
        where = f"key '{name}': " if name else ""
        return ConfigError(f"{where}expected {expected}, found {found_text}", path=self.path)

    def has(self, key: str) -> bool:
        """Whether the table sets ``key``."""
        return key in self.raw

    def _get(self, key: str, default: Any, expected: str) -> Any:
        if key in self.raw:
            return self.raw[key]
        if default is _MISSING:
            raise self.error(key, expected, _MISSING)
        return default

    def only(self, known: Iterable[str], what: str = "one of the known keys") -> None:
        """Reject keys the schema does not know (a typo silently ignored is a wrong run)."""
        known = list(known)
        unknown = sorted(set(self.raw) - set(known))
        if unknown:
            raise self.error(
                unknown[0], f"{what} ({', '.join(sorted(known))})",
                _Found(f"the unknown key '{unknown[0]}'"),
            )

    # ------------------------------------------------------------------ values
    def table(self, key: str, default: Any = _MISSING) -> ConfigTable:
        """A sub-table (``default`` is used when absent, e.g. ``{}``)."""
        raw = self._get(key, default, "a table")
        if not isinstance(raw, dict):
            raise self.error(key, "a table", raw)
        return ConfigTable(raw, self.path, self.key(key))

    def tables(self, key: str) -> list[ConfigTable]:
        """An array of tables (``[[key]]``)."""
        raw = self._get(key, _MISSING, "an array of tables [[...]]")
        if not isinstance(raw, list) or not raw or not all(isinstance(t, dict) for t in raw):
            raise self.error(key, "a non-empty array of tables [[...]]", raw)
        return [ConfigTable(t, self.path, f"{self.key(key)}[{i + 1}]") for i, t in enumerate(raw)]

    def number(
        self, key: str, default: Any = _MISSING, *, lo: float = -math.inf,
        hi: float = math.inf, positive: bool = False,
    ) -> float:
        """A finite number in ``[lo, hi]`` (``> 0`` too with ``positive``)."""
        expected = "a finite number" + (" > 0" if positive else "") + _range(lo, hi)
        raw = self._get(key, default, expected)
        return self._number(key, raw, expected, lo, hi, positive)

    def _number(
        self, key: str, raw: Any, expected: str, lo: float, hi: float, positive: bool
    ) -> float:
        if isinstance(raw, bool) or not isinstance(raw, int | float):
            raise self.error(key, expected, raw)
        value = float(raw)
        if not math.isfinite(value) or not lo <= value <= hi or (positive and value <= 0):
            raise self.error(key, expected, raw)
        return value

    def integer(
        self, key: str, default: Any = _MISSING, *, lo: float = -math.inf, hi: float = math.inf
    ) -> int:
        """A whole number in ``[lo, hi]`` (``3.0`` is accepted; ``nan``, ``inf``, 3.5 are not)."""
        expected = "a whole number" + _range(lo, hi)
        raw = self._get(key, default, expected)
        if isinstance(raw, bool) or not isinstance(raw, int | float):
            raise self.error(key, expected, raw)
        if not math.isfinite(raw) or raw != int(raw) or not lo <= raw <= hi:
            raise self.error(key, expected, raw)
        return int(raw)

    def boolean(self, key: str, default: Any = _MISSING) -> bool:
        """``true`` or ``false``."""
        raw = self._get(key, default, "true or false")
        if not isinstance(raw, bool):
            raise self.error(key, "true or false", raw)
        return raw

    def string(
        self, key: str, default: Any = _MISSING, *, choices: Sequence[str] | None = None
    ) -> str:
        """A text value (one of ``choices`` when given)."""
        expected = (
            "one of " + ", ".join(repr(c) for c in choices) if choices else "a text in quotes"
        )
        raw = self._get(key, default, expected)
        if not isinstance(raw, str) or (choices and raw not in choices):
            raise self.error(key, expected, raw)
        return raw

    def numbers(
        self, key: str, default: Any = _MISSING, *, length: int | None = None,
        min_length: int = 1, lo: float = -math.inf, hi: float = math.inf,
        positive: bool = False,
    ) -> tuple[float, ...]:
        """A list of finite numbers (exactly ``length`` of them when given)."""
        count = f"{length}" if length is not None else f"at least {min_length}"
        each = "finite numbers" + (" > 0" if positive else "") + _range(lo, hi)
        expected = f"a list of {count} {each}"
        raw = self._get(key, default, expected)
        if not isinstance(raw, list | tuple) or (
            len(raw) != length if length is not None else len(raw) < min_length
        ):
            raise self.error(key, expected, raw)
        values = []
        for i, item in enumerate(raw):
            try:
                values.append(self._number(key, item, expected, lo, hi, positive))
            except ConfigError:
                raise self.error(f"{key}[{i}]", f"one of {each}", item) from None
        return tuple(values)

    def strings(self, key: str, default: Any = _MISSING) -> tuple[str, ...]:
        """A list of non-empty texts (a single text counts as a list of one)."""
        expected = "a list of non-empty texts in quotes"
        raw = self._get(key, default, expected)
        if isinstance(raw, str):
            raw = [raw]
        if not isinstance(raw, list) or not raw or not all(isinstance(n, str) and n for n in raw):
            raise self.error(key, expected, raw)
        return tuple(raw)

    def check(self, ok: bool, key: str, expected: str, found: Any) -> None:
        """Raise the schema message unless ``ok`` (relations between keys)."""
        if not ok:
            raise self.error(key, expected, found)


def config_file(path: str | Path) -> ConfigTable:
    """Load a TOML file as the top-level :class:`ConfigTable` of the schema layer."""
    return ConfigTable(load_toml(path), path)
