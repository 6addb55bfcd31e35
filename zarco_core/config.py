"""TOML configuration: load, override by dotted path, validate into dataclasses.

The schema *is* the dataclasses (``settings.py`` for the runtime,
``drivers.sim.params`` for the simulated world): each field has a type, a
default, and optional ``metadata`` with ``min``/``max`` (inclusive range),
``choices`` (allowed strings), ``unit`` and ``doc``.  A dataclass may define
``validate(self)`` raising ``ValueError("key: reason")`` for checks across
fields (a non-monotone thruster table, say).

Any problem is one :class:`ConfigError` naming the file, the dotted key and
the reason; callers build the whole configuration before starting anything,
so nothing half-starts.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import tomllib
import types
import typing
from pathlib import Path
from typing import Any, TypeVar, get_args, get_origin, get_type_hints

from zarco_core.paths import PathError, read_text

T = TypeVar("T")


class ConfigError(ValueError):
    """A configuration problem: ``file``, dotted ``key`` and ``reason``."""

    def __init__(self, file: str, key: str, reason: str) -> None:
        self.file = file
        self.key = key
        self.reason = reason
        super().__init__(f"{file}: {key}: {reason}" if key else f"{file}: {reason}")


def load_toml(path: str | Path) -> dict[str, Any]:
    """Read a TOML file.  A file that cannot be read (missing, a directory,
    unreadable, not UTF-8) or has a syntax error is a ConfigError naming the
    file and the reason (the position, for a syntax error)."""
    try:
        text = read_text(path)
    except PathError as exc:
        reason = "file not found" if exc.reason == "no such file or directory" else exc.reason
        raise ConfigError(str(path), "", reason) from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(str(path), "", f"TOML syntax error: {exc}") from None


def parse_override(text: str, file: str = "--set") -> tuple[list[str], Any]:
    """``a.b.c=VALUE`` → (["a","b","c"], value).  VALUE is read as a TOML
    value (``1.5``, ``true``, ``[1, 2]``, ``"s"``); a bare word is a string."""
    if "=" not in text:
        raise ConfigError(file, text, "an override must look like KEY=VALUE")
    key, raw = text.split("=", 1)
    key = key.strip()
    if not key or any(not part for part in key.split(".")):
        raise ConfigError(file, key, "empty key in override")
    try:
        value = tomllib.loads(f"v = {raw.strip()}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw.strip()
    return key.split("."), value


def apply_overrides(data: dict[str, Any], overrides: list[str], file: str = "--set") -> None:
    """Apply ``KEY=VALUE`` overrides to a raw TOML dict in place."""
    for text in overrides:
        path, value = parse_override(text, file)
        node = data
        for i, part in enumerate(path[:-1]):
            nxt = node.setdefault(part, {})
            if not isinstance(nxt, dict):
                raise ConfigError(file, ".".join(path[: i + 1]), "is not a table")
            node = nxt
        node[path[-1]] = value


def _type_name(tp: Any) -> str:
    origin = get_origin(tp)
    if origin is None:
        return getattr(tp, "__name__", str(tp))
    return str(tp).replace("typing.", "")


def _is_optional(tp: Any) -> tuple[bool, Any]:
    origin = get_origin(tp)
    if origin in (typing.Union, types.UnionType):
        args = [a for a in get_args(tp) if a is not type(None)]
        if len(args) == 1 and len(get_args(tp)) == 2:
            return True, args[0]
    return False, tp


def _coerce(value: Any, tp: Any, file: str, key: str) -> Any:
    optional, tp = _is_optional(tp)
    if tp is Any or tp is object:  # free-form (a command's arguments): any TOML value
        return value
    if value is None:
        if optional:
            return None
        raise ConfigError(file, key, "missing value")
    origin = get_origin(tp)
    if dataclasses.is_dataclass(tp):
        if not isinstance(value, dict):
            raise ConfigError(file, key, f"expected a table, got {type(value).__name__}")
        return build(tp, value, file, key)  # type: ignore[arg-type]
    if tp is bool:
        if not isinstance(value, bool):
            raise ConfigError(file, key, f"expected true/false, got {value!r}")
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(file, key, f"expected an integer, got {value!r}")
        return value
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(file, key, f"expected a number, got {value!r}")
        f = float(value)
        if not math.isfinite(f):
            raise ConfigError(file, key, f"must be finite, got {value!r}")
        return f
    if tp is str:
        if not isinstance(value, str):
            raise ConfigError(file, key, f"expected a string, got {value!r}")
        return value
    if origin is list:
        if not isinstance(value, list):
            raise ConfigError(file, key, f"expected a list, got {value!r}")
        (item_tp,) = get_args(tp)
        return [_coerce(v, item_tp, file, f"{key}[{i}]") for i, v in enumerate(value)]
    if origin is dict:
        if not isinstance(value, dict):
            raise ConfigError(file, key, f"expected a table, got {value!r}")
        _, val_tp = get_args(tp)
        return {k: _coerce(v, val_tp, file, f"{key}.{k}") for k, v in value.items()}
    raise ConfigError(file, key, f"unsupported type {_type_name(tp)}")  # pragma: no cover


def _check_range(value: Any, meta: typing.Mapping[str, Any], file: str, key: str) -> None:
    if value is None:
        return
    unit = f" {meta['unit']}" if meta.get("unit") else ""
    if "choices" in meta and value not in meta["choices"]:
        raise ConfigError(file, key, f"must be one of {list(meta['choices'])}, got {value!r}")
    values = value if isinstance(value, list) else [value]
    for v in values:
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            if "min" in meta and v < meta["min"]:
                raise ConfigError(file, key, f"must be ≥ {meta['min']}{unit}, got {v}")
            if "max" in meta and v > meta["max"]:
                raise ConfigError(file, key, f"must be ≤ {meta['max']}{unit}, got {v}")


def build(cls: type[T], data: dict[str, Any], file: str, prefix: str = "") -> T:
    """Validate ``data`` against dataclass ``cls`` and return an instance.

    Unknown keys, wrong types, missing values and out-of-range values raise
    ConfigError(file, dotted key, reason).
    """
    hints = get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}  # type: ignore[arg-type]
    for k in data:
        if k not in fields:
            close = difflib.get_close_matches(k, list(fields), n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise ConfigError(file, f"{prefix}.{k}" if prefix else k, f"unknown key{hint}")
    kwargs: dict[str, Any] = {}
    for name, f in fields.items():
        key = f"{prefix}.{name}" if prefix else name
        if name in data:
            val = _coerce(data[name], hints[name], file, key)
            _check_range(val, f.metadata, file, key)
            kwargs[name] = val
        elif f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
            raise ConfigError(file, key, "missing value (required)")
    obj = cls(**kwargs)
    validate = getattr(obj, "validate", None)
    if callable(validate):
        try:
            validate()
        except ValueError as exc:
            sub, _, reason = str(exc).partition(": ")
            if not reason:
                sub, reason = "", str(exc)
            full = ".".join(p for p in (prefix, sub) if p)
            raise ConfigError(file, full, reason) from None
    return obj


def spec(default: Any, unit: str = "", doc: str = "", **meta: Any) -> Any:
    """Shorthand for a dataclass field with config metadata."""
    md = {"unit": unit, "doc": doc, **meta}
    if callable(default) or isinstance(default, (list, dict)) or dataclasses.is_dataclass(default):
        factory = default if callable(default) else (lambda d=default: _copy(d))
        return dataclasses.field(default_factory=factory, metadata=md)
    return dataclasses.field(default=default, metadata=md)


def _copy(d: Any) -> Any:
    import copy

    return copy.deepcopy(d)


def to_dict(obj: Any) -> dict[str, Any]:
    """Dataclass → plain dict (for reports)."""
    return dataclasses.asdict(obj)
