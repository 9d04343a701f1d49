"""Typed, validated access to TOML config files.

A ``Section`` wraps one TOML table and remembers the file and dotted key path, so every lookup
that fails says exactly where (``configs/hands/<hand>/hand.toml: fingers[2].joints: expected
a list of strings``). Config dataclasses are built from Sections; nothing reads raw dicts.
"""

from __future__ import annotations

import builtins
import math
import tomllib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from sim.errors import ConfigError

_MISSING = object()


class Section:
    """One table of a TOML file, with its location for error messages.

    Its readers are named after the types they return (``str``, ``bool``, ``int``, ``float``),
    which shadows those names in the class body: the annotations below them spell the
    builtins ``builtins.str`` etc."""

    def __init__(self, data: dict[str, Any], file: Path | str, path: str = "") -> None:
        self.data = data
        self.file = str(file)
        self.path = path

    def where(self, key: str | None = None) -> str:
        dotted = ".".join(p for p in (self.path, key) if p)
        return f"{self.file}: {dotted}" if dotted else self.file

    def error(self, key: str | None, expected: str) -> ConfigError:
        return ConfigError(f"{self.where(key)}: {expected}")

    def __contains__(self, key: str) -> bool:
        return key in self.data

    def _raw(self, key: str, default: Any) -> Any:
        if key in self.data:
            return self.data[key]
        if default is _MISSING:
            raise self.error(key, "missing required key")
        return default

    def str(self, key: str, default: Any = _MISSING) -> str:
        value = self._raw(key, default)
        if value is not default and not isinstance(value, str):
            raise self.error(key, f"expected a string, got {value!r}")
        return value

    def bool(self, key: builtins.str, default: Any = _MISSING) -> builtins.bool:
        value = self._raw(key, default)
        if value is not default and not isinstance(value, bool):
            raise self.error(key, f"expected true or false, got {value!r}")
        return value

    def int(self, key: builtins.str, default: Any = _MISSING, *,
            min: builtins.int | None = None) -> builtins.int:
        value = self._raw(key, default)
        if value is default:
            return value
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(key, f"expected an integer, got {value!r}")
        if min is not None and value < min:
            raise self.error(key, f"expected an integer >= {min}, got {value}")
        return value

    def float(self, key: builtins.str, default: Any = _MISSING, *,
              min: builtins.float | None = None,
              max: builtins.float | None = None) -> builtins.float:
        value = self._raw(key, default)
        if value is default:
            return value
        if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
            raise self.error(key, f"expected a finite number, got {value!r}")
        if (min is not None and value < min) or (max is not None and value > max):
            raise self.error(key, f"expected a number in [{min}, {max}], got {value}")
        return float(value)

    def like(self, key: builtins.str,
             default: builtins.bool | builtins.int | builtins.float | builtins.str) -> Any:
        """``key`` read with the type of its ``default`` (bool, int, float or str), the
        default when absent: what a flat parameter table of a dataclass needs per field."""
        if isinstance(default, bool):
            return self.bool(key, default)
        if isinstance(default, int):
            return self.int(key, default)
        if isinstance(default, float):
            return self.float(key, default)
        return self.str(key, default)

    def floats(self, key: builtins.str, length: builtins.int | None = None,
               default: Any = _MISSING) -> list[builtins.float]:
        value = self._raw(key, default)
        if value is default:
            return value
        ok = isinstance(value, list) and all(
            isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
            for v in value)
        if not ok or (length is not None and len(value) != length):
            size = f"{length} " if length is not None else ""
            raise self.error(key, f"expected a list of {size}finite numbers, got {value!r}")
        return [float(v) for v in value]

    def strs(self, key: builtins.str, default: Any = _MISSING) -> list[builtins.str]:
        value = self._raw(key, default)
        if value is default:
            return value
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            raise self.error(key, f"expected a list of strings, got {value!r}")
        return list(value)

    def section(self, key: builtins.str, default: Any = _MISSING) -> Section:
        value = self._raw(key, default)
        if value is default:
            return Section({}, self.file, ".".join(p for p in (self.path, key) if p))
        if not isinstance(value, dict):
            raise self.error(key, f"expected a table, got {value!r}")
        return Section(value, self.file, ".".join(p for p in (self.path, key) if p))

    def sections(self, key: builtins.str) -> Iterator[Section]:
        value = self._raw(key, [])
        if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
            raise self.error(key, "expected an array of tables ([[...]])")
        base = ".".join(p for p in (self.path, key) if p)
        for i, item in enumerate(value):
            yield Section(item, self.file, f"{base}[{i}]")

    def reject_unknown(self, allowed: set[builtins.str]) -> None:
        """Typos in config keys silently fall back to defaults otherwise; refuse them."""
        unknown = sorted(set(self.data) - allowed)
        if unknown:
            raise self.error(None, f"unknown key(s) {unknown}; allowed: {sorted(allowed)}")


def load_toml(path: Path | str) -> Section:
    """Parse a TOML file into a root Section; a missing file or syntax error names the file."""
    path = Path(path)
    try:
        with path.open("rb") as f:
            return Section(tomllib.load(f), path)
    except FileNotFoundError:
        raise ConfigError(f"{path}: config file not found") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: invalid TOML: {exc}") from None
