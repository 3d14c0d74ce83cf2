"""Config dataclass <-> flat parameter values: the schema of the ROS parameters, without ROS.

Each leaf field of a frozen config dataclass is one parameter ``<prefix>.<field>`` (nested: dotted,
``fpdeso.fuzzy.k_e``). Its kind comes from the type hint (``float``, ``int``, ``bool``, ``str`` or a
``Literal``, ``tuple[float, float]`` per joint, ``tuple[float, ...]``, the same of ``int``), its range from
the field metadata (:mod:`smm_schema.ranges`), its description from the dataclass's ``Attributes:``
section. rclpy side: :mod:`smm_node_runtime.parameters`.
"""

from __future__ import annotations

import dataclasses
import enum
import inspect
import math
import re
import typing
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal, TypeVar

from smm_schema.ranges import Range, field_range

__all__ = [
    "INT64_MAX",
    "INT64_MIN",
    "NUMERIC_KINDS",
    "PER_JOINT_LENGTH",
    "ConfigField",
    "FieldKind",
    "choices",
    "config_fields",
    "config_from_parameters",
    "config_to_parameters",
    "constraints",
    "docstring_attributes",
    "integer_span",
    "parameter_name",
    "parameter_value",
    "unranged_fields",
    "value_at",
]

ConfigT = TypeVar("ConfigT")

PER_JOINT_LENGTH = 2
"""Length of a per-joint field ``tuple[float, float]`` (alpha, beta)."""

INT64_MIN, INT64_MAX = -(2**63), 2**63 - 1
"""The ends of a ROS integer parameter."""


class FieldKind(enum.Enum):
    """How a leaf field of a config maps onto a ROS parameter type."""

    DOUBLE = "double"
    INTEGER = "integer"
    BOOL = "bool"
    STRING = "string"
    DOUBLE_ARRAY = "double_array"
    INTEGER_ARRAY = "integer_array"

    @property
    def numeric(self) -> bool:
        """True for the kinds whose values (or elements) are numbers: they must declare a range."""
        return self in NUMERIC_KINDS


NUMERIC_KINDS = frozenset(
    {FieldKind.DOUBLE, FieldKind.INTEGER, FieldKind.DOUBLE_ARRAY, FieldKind.INTEGER_ARRAY}
)
"""Kinds whose fields must declare a range (or :func:`~smm_schema.ranges.no_range`)."""


@dataclass(frozen=True)
class ConfigField:
    """One leaf field of a (possibly nested) config dataclass, i.e. one ROS parameter.

    Attributes:
        name: Parameter name relative to the prefix, dotted for nested fields (e.g. ``fuzzy.k_e``).
        path: Attribute path from the top-level config to the field (e.g. ``("fuzzy", "k_e")``).
        kind: ROS parameter type of the field.
        length: Required number of values for a fixed-length tuple field, None for scalars and
            variable-length tuples.
        description: Human-readable meaning and unit (from the docstring), may be empty.
        value_range: Range of a number field, of each element for an array (its field metadata), or None.
        choices: The values a ``Literal`` string field admits, empty for every other field.
    """

    name: str
    path: tuple[str, ...]
    kind: FieldKind
    length: int | None
    description: str
    value_range: Range | None = None
    choices: tuple[str, ...] = ()


def parameter_name(prefix: str, name: str) -> str:
    """Return the full parameter name ``<prefix>.<name>`` (just ``name`` for an empty prefix)."""
    return f"{prefix}.{name}" if prefix else name


# ------------------------------------------------------------------------------------- introspection

_ATTRIBUTES_HEADER = re.compile(r"^(\s*)Attributes:\s*$")
_ATTRIBUTE_ENTRY = re.compile(r"^(\w+)(?:\s*\([^)]*\))?:\s*(.*)$")


def docstring_attributes(cls: type) -> dict[str, str]:
    """Parse the Google-style ``Attributes:`` section of ``cls``'s docstring.

    Args:
        cls: Any class.

    Returns:
        ``{attribute name: description}`` with continuation lines joined by single spaces; empty when the
        class has no such section.
    """
    doc = inspect.getdoc(cls) or ""
    lines = doc.splitlines()
    result: dict[str, str] = {}
    inside = False
    entry_indent: int | None = None
    current: str | None = None
    for line in lines:
        if not inside:
            inside = _ATTRIBUTES_HEADER.match(line) is not None
            continue
        if not line.strip():
            continue
        indent = len(line) - len(line.lstrip())
        if entry_indent is None:
            entry_indent = indent
        if indent < entry_indent or (indent == 0 and line.rstrip().endswith(":")):
            break  # the next section starts
        match = _ATTRIBUTE_ENTRY.match(line.strip())
        if indent == entry_indent and match is not None:
            current = match.group(1)
            result[current] = match.group(2).strip()
        elif current is not None:
            result[current] = f"{result[current]} {line.strip()}".strip()
    return result


def _leaf_kind(hint: Any, where: str) -> tuple[FieldKind, int | None]:
    """Map a field's type hint to its parameter kind and required length."""
    if hint is bool:
        return FieldKind.BOOL, None
    if hint is float:
        return FieldKind.DOUBLE, None
    if hint is int:
        return FieldKind.INTEGER, None
    if hint is str:
        return FieldKind.STRING, None
    origin = typing.get_origin(hint)
    arguments = typing.get_args(hint)
    if origin is Literal and arguments and all(isinstance(value, str) for value in arguments):
        return FieldKind.STRING, None
    if origin is tuple and arguments:
        variable = len(arguments) == 2 and arguments[1] is Ellipsis
        element_types = {arguments[0]} if variable else set(arguments)
        length = None if variable else len(arguments)
        if element_types == {float}:
            return FieldKind.DOUBLE_ARRAY, length
        if element_types == {int}:
            return FieldKind.INTEGER_ARRAY, length
    raise TypeError(f"{where}: field type {hint!r} has no ROS parameter mapping")


def config_fields(config_cls: type) -> tuple[ConfigField, ...]:
    """List the leaf fields of a frozen config dataclass, nested dataclasses flattened.

    Args:
        config_cls: A dataclass type (fields with ``init=False`` are skipped: they are derived).

    Returns:
        The fields in declaration order (depth-first for nested dataclasses).

    Raises:
        TypeError: ``config_cls`` is not a dataclass, or a field's type has no parameter mapping.
    """
    return _config_fields(config_cls, ())


def _config_fields(config_cls: type, path: tuple[str, ...]) -> tuple[ConfigField, ...]:
    if not (isinstance(config_cls, type) and dataclasses.is_dataclass(config_cls)):
        raise TypeError(f"{config_cls!r} is not a dataclass type")
    hints = typing.get_type_hints(config_cls)
    docs = docstring_attributes(config_cls)
    result: list[ConfigField] = []
    for field in dataclasses.fields(config_cls):
        if not field.init:
            continue
        hint = hints[field.name]
        field_path = (*path, field.name)
        if isinstance(hint, type) and dataclasses.is_dataclass(hint):
            result.extend(_config_fields(hint, field_path))
            continue
        kind, length = _leaf_kind(hint, ".".join(field_path))
        description = docs.get(field.name, "")
        value_range = field_range(field) if kind.numeric else None
        result.append(
            ConfigField(
                ".".join(field_path), field_path, kind, length, description, value_range, choices(hint)
            )
        )
    return tuple(result)


def choices(hint: Any) -> tuple[str, ...]:
    """The strings a ``Literal`` type hint admits, in order (empty for any other hint)."""
    arguments = typing.get_args(hint) if typing.get_origin(hint) is Literal else ()
    return tuple(value for value in arguments if isinstance(value, str))


def unranged_fields(config_cls: type) -> tuple[str, ...]:
    """Names of the numeric leaf fields of ``config_cls`` that declare no range in their metadata."""
    return tuple(
        field.name for field in config_fields(config_cls) if field.kind.numeric and field.value_range is None
    )


def value_at(config: object, path: Sequence[str]) -> Any:
    """The value of the field at attribute ``path`` of ``config``."""
    value = config
    for attribute in path:
        value = getattr(value, attribute)
    return value


def integer_span(value_range: Range) -> tuple[int, int]:
    """The first and last integer in ``value_range`` (an open end moves one inward; int64 for no end)."""
    first, last = INT64_MIN, INT64_MAX
    if math.isfinite(value_range.low):
        first = math.floor(value_range.low) + 1 if value_range.low_open else math.ceil(value_range.low)
    if math.isfinite(value_range.high):
        last = math.ceil(value_range.high) - 1 if value_range.high_open else math.floor(value_range.high)
    return first, last


def constraints(field: ConfigField) -> str:
    """What a closed ROS range cannot say of ``field``: its array length, open ends, element range.

    E.g. ``"2 values, per joint (alpha, beta), each > 0"`` or ``"in (0, 1]"``; empty when the ROS range
    (or no range) says it all.
    """
    parts = []
    if field.length == PER_JOINT_LENGTH:
        parts.append("2 values, per joint (alpha, beta)")
    elif field.length is not None:
        parts.append(f"{field.length} values")
    value_range = field.value_range
    if value_range is not None and not value_range.unbounded:
        array = field.kind in (FieldKind.DOUBLE_ARRAY, FieldKind.INTEGER_ARRAY)
        open_finite_end = (value_range.low_open and math.isfinite(value_range.low)) or (
            value_range.high_open and math.isfinite(value_range.high)
        )
        if array:
            parts.append(f"each {value_range.requirement()}")
        elif open_finite_end and field.kind is FieldKind.DOUBLE:
            parts.append(value_range.requirement())
    return ", ".join(parts)


# ------------------------------------------------------------------------------- value conversions


def parameter_value(field: ConfigField, value: Any) -> Any:
    """Config field value -> value of the declared ROS parameter (list for arrays)."""
    if field.kind is FieldKind.DOUBLE_ARRAY:
        return [float(v) for v in value]
    if field.kind is FieldKind.INTEGER_ARRAY:
        return [int(v) for v in value]
    if field.kind is FieldKind.DOUBLE:
        return float(value)
    return value


def _as_float(value: object, name: str) -> float:
    # Finiteness and sign are the dataclass's business: some fields accept inf ("no limit").
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"{name} must be a number, got {value!r}")
    return float(value)


def _exact_int(value: object, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise ValueError(f"{name} must be an integer, got {value!r}")
    return int(value)


def _to_field_value(field: ConfigField, value: Any, name: str) -> Any:
    """Parameter value -> config field value, checking type and length."""
    kind = field.kind
    if kind is FieldKind.DOUBLE:
        return _as_float(value, name)
    if kind is FieldKind.INTEGER:
        return _exact_int(value, name)
    if kind is FieldKind.BOOL:
        if not isinstance(value, bool):
            raise ValueError(f"{name} must be a bool, got {value!r}")
        return value
    if kind is FieldKind.STRING:
        if not isinstance(value, str):
            raise ValueError(f"{name} must be a string, got {value!r}")
        return value
    if isinstance(value, (str, bytes)) or not isinstance(value, Iterable):
        raise ValueError(f"{name} must be an array, got {value!r}")
    items = list(value)
    if field.length is not None and len(items) != field.length:
        what = " (alpha, beta)" if field.length == PER_JOINT_LENGTH else ""
        raise ValueError(f"{name} must have {field.length} values{what}, got {len(items)}: {items}")
    convert: Callable[[object, str], Any] = _as_float if kind is FieldKind.DOUBLE_ARRAY else _exact_int
    return tuple(convert(item, f"{name}[{index}]") for index, item in enumerate(items))


def config_to_parameters(config: object, prefix: str = "") -> dict[str, Any]:
    """Flatten a config instance into ``{full parameter name: ROS parameter value}``.

    Args:
        config: A config dataclass instance.
        prefix: Parameter name prefix (without trailing dot); ``""`` for none.

    Returns:
        Values in the types the ROS parameters are declared with (lists for arrays, floats for doubles).
    """
    return {
        parameter_name(prefix, field.name): parameter_value(field, value_at(config, field.path))
        for field in config_fields(type(config))
    }


def config_from_parameters(
    config_cls: type[ConfigT], current: ConfigT, overrides: Mapping[str, Any], prefix: str = ""
) -> ConfigT:
    """Build a NEW config from ``current`` with some fields replaced by parameter values.

    Args:
        config_cls: The config dataclass type (``current`` must be an instance of it).
        current: The config the unchanged fields are taken from.
        overrides: ``{full parameter name: value}``; names not under ``prefix`` or not naming a field are
            ignored (they belong to something else), so the whole ``set_parameters`` list can be passed.
        prefix: Parameter name prefix of this config (without trailing dot).

    Returns:
        The new config, validated by the dataclass(es) ``__post_init__``; ``current`` when nothing applies.

    Raises:
        ValueError: a value has the wrong type or length (message names the parameter and the value), or
            the dataclass rejected the new config (its own message).
    """
    if not isinstance(current, config_cls):
        raise TypeError(f"current must be a {config_cls.__name__}, got {type(current).__name__}")
    by_name = {parameter_name(prefix, field.name): field for field in config_fields(config_cls)}
    changes: dict[tuple[str, ...], Any] = {}
    for name, value in overrides.items():
        field = by_name.get(name)
        if field is not None:
            changes[field.path] = _to_field_value(field, value, name)
    if not changes:
        return current
    return typing.cast(ConfigT, _replaced(current, changes))


def _replaced(config: Any, changes: Mapping[tuple[str, ...], Any]) -> Any:
    """dataclasses.replace, recursively for nested paths (inner configs are validated first)."""
    direct = {path[0]: value for path, value in changes.items() if len(path) == 1}
    nested: dict[str, dict[tuple[str, ...], Any]] = {}
    for path, value in changes.items():
        if len(path) > 1:
            nested.setdefault(path[0], {})[path[1:]] = value
    for attribute, inner_changes in nested.items():
        direct[attribute] = _replaced(getattr(config, attribute), inner_changes)
    return dataclasses.replace(config, **direct)
