"""ROS 2 parameters <-> frozen config dataclasses, generically, for every node of the stack.

One algorithm config is one frozen dataclass (see ``docs/DESIGN.md``); each of its fields becomes one ROS
parameter, named ``<prefix>.<field>`` (nested dataclasses are flattened with a dotted path, e.g.
``fpdeso.fuzzy.k_e``). Supported field types and their parameter types:

=============================  ======================  ==========================================
field type                     ROS parameter type      value check done here
=============================  ======================  ==========================================
``float``                      ``double``              number (int accepted, converted)
``int``                        ``integer``             integer, not bool
``bool``                       ``bool``                bool
``str`` / ``Literal["a", ..]``  ``string``              str (the dataclass checks allowed values)
``tuple[float, float]``        ``double_array``        exactly 2 numbers (alpha, beta)
``tuple[float, ...]``          ``double_array``        any length
``tuple[int, int]`` / ``...``  ``integer_array``       length as for doubles
nested frozen dataclass        flattened, dotted       recursively
=============================  ======================  ==========================================

Everything beyond that (finiteness, signs, bounds, orderings) is the dataclass's own ``__post_init__``
validation (some fields accept infinity as "no limit"); its
``ValueError`` message is what a rejected ``set_parameters`` call reports as ``reason``. ROS ranges
(``FloatingPointRange``) only apply to scalars, so array bounds are always checked by the dataclass.

Ranges: a scalar field's ROS range (``FloatingPointRange`` / ``IntegerRange``, closed) comes from its
dataclass field metadata (:func:`bounds`, checked by :func:`check_bounds` in ``__post_init__``), else from
the bound its docstring states (``> 0``, ``>= 3``, ``<= 1``: the ROS range is closed, the dataclass keeps
refusing the open end), so every node declares the same ranges without listing them.

Descriptions come from the dataclass docstring's Google-style ``Attributes:`` section (one source of truth
for units and meaning), unless overridden by the ``descriptions`` argument.

The usual way to use this is :class:`ConfigParameters`: it declares the parameters, builds the initial
config from the declared values (parameter overrides and ``--params-file`` included), validates every later
change as a whole new config (rejecting it with the ``ValueError`` message), and swaps the config only after
the change succeeded, so a node's step sees either the old config or the new one, never a mix.
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
from typing import Any, Generic, Literal, TypeVar

from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    ParameterType,
    SetParametersResult,
)
from rclpy.exceptions import InvalidParameterValueException
from rclpy.node import Node
from rclpy.parameter import Parameter

from smm_node_runtime.ranges import RANGE_METADATA, bounds, check_bounds

__all__ = [
    "RANGE_METADATA",
    "ConfigField",
    "ConfigParameters",
    "FieldKind",
    "bounds",
    "check_bounds",
    "config_fields",
    "config_from_parameters",
    "config_to_parameters",
    "declare_config_parameters",
    "docstring_attributes",
    "parameter_name",
]

ConfigT = TypeVar("ConfigT")

PER_JOINT_LENGTH = 2
"""Length of a per-joint field ``tuple[float, float]`` (alpha, beta)."""

_INT64_MAX = 2**63 - 1


class FieldKind(enum.Enum):
    """How a leaf field of a config maps onto a ROS parameter type."""

    DOUBLE = ParameterType.PARAMETER_DOUBLE
    INTEGER = ParameterType.PARAMETER_INTEGER
    BOOL = ParameterType.PARAMETER_BOOL
    STRING = ParameterType.PARAMETER_STRING
    DOUBLE_ARRAY = ParameterType.PARAMETER_DOUBLE_ARRAY
    INTEGER_ARRAY = ParameterType.PARAMETER_INTEGER_ARRAY


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
        value_range: Closed range of a scalar number field (from :func:`bounds` or the docstring), or None.
    """

    name: str
    path: tuple[str, ...]
    kind: FieldKind
    length: int | None
    description: str
    value_range: tuple[float, float] | None = None


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
        value_range = field.metadata.get(RANGE_METADATA)
        if value_range is None and kind in (FieldKind.DOUBLE, FieldKind.INTEGER):
            value_range = stated_range(description)
        if kind not in (FieldKind.DOUBLE, FieldKind.INTEGER):
            value_range = None
        result.append(ConfigField(".".join(field_path), field_path, kind, length, description, value_range))
    return tuple(result)


_NUMBER = r"(-?\d+(?:\.\d+)?(?:[eE]-?\d+)?)"
_NOT_A_UNIT = r"(?!\w)(?!\s*(?:ns|us|ms|s|rad|Hz|N|m|kg)\b)"  # ">= 1 ns" is no bound on a value in seconds
_LOWER = re.compile(r"(?<![<>=-])(>=?)\s*" + _NUMBER + _NOT_A_UNIT)
_UPPER = re.compile(r"(?<![<>=-])(<=?)\s*" + _NUMBER + _NOT_A_UNIT)


def stated_range(description: str) -> tuple[float, float] | None:
    """The closed range a docstring states for a scalar (``> 0`` gives [0, inf]); None if it states none."""
    lows = [float(match.group(2)) for match in _LOWER.finditer(description)]
    highs = [float(match.group(2)) for match in _UPPER.finditer(description)]
    if not lows and not highs:
        return None
    return (max(lows) if lows else -math.inf, min(highs) if highs else math.inf)


def _value_at(config: object, path: Sequence[str]) -> Any:
    value = config
    for attribute in path:
        value = getattr(value, attribute)
    return value


# ------------------------------------------------------------------------------- value conversions


def _to_parameter_value(field: ConfigField, value: Any) -> Any:
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
        parameter_name(prefix, field.name): _to_parameter_value(field, _value_at(config, field.path))
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


# ------------------------------------------------------------------------------------------ ROS side


def _descriptor(
    field: ConfigField,
    full_name: str,
    description: str,
    value_range: tuple[float, float] | None,
    read_only: bool,
) -> ParameterDescriptor:
    constraints = ""
    if field.length == PER_JOINT_LENGTH:
        constraints = "2 values, per joint (alpha, beta)"
    elif field.length is not None:
        constraints = f"{field.length} values"
    descriptor = ParameterDescriptor(
        name=full_name,
        type=field.kind.value,
        description=description or field.name,
        additional_constraints=constraints,
        read_only=read_only,
    )
    if value_range is not None:
        low, high = value_range
        if field.kind is FieldKind.INTEGER:
            low = -_INT64_MAX - 1 if math.isinf(low) else low
            high = _INT64_MAX if math.isinf(high) else high
        if field.kind is FieldKind.DOUBLE:
            descriptor.floating_point_range = [
                FloatingPointRange(from_value=float(low), to_value=float(high), step=0.0)
            ]
        elif field.kind is FieldKind.INTEGER:
            descriptor.integer_range = [IntegerRange(from_value=int(low), to_value=int(high), step=1)]
        else:
            raise ValueError(f"{full_name}: a range applies to scalar fields only (ROS 2 limitation)")
    return descriptor


def declare_config_parameters(
    node: Node,
    prefix: str,
    config_instance: ConfigT,
    *,
    descriptions: Mapping[str, str] | None = None,
    ranges: Mapping[str, tuple[float, float]] | None = None,
    read_only: bool = False,
) -> ConfigT:
    """Declare one ROS parameter per leaf field of ``config_instance`` and build the config they give.

    Declared values come from the node's parameter overrides (``parameter_overrides``, ``--params-file``,
    ``-p``) when present, else from ``config_instance``. Note a YAML array of integers (``[4050, 4150]``)
    is an integer array to ROS and is refused for a double-array parameter: write ``[4050.0, 4150.0]``.

    Args:
        node: The node.
        prefix: Parameter name prefix without trailing dot (``""`` for none).
        config_instance: Default values.
        descriptions: Overrides of the docstring descriptions, keyed by relative name (``fuzzy.k_e``).
        ranges: ``FloatingPointRange``/``IntegerRange`` bounds for scalar fields, keyed by relative name.
        read_only: Declare the parameters read-only (settable only at start-up).

    Returns:
        The config built from the declared values.

    Raises:
        ValueError: the declared values do not form a valid config (message of the dataclass).
        rclpy.exceptions.InvalidParameterTypeException: an override has the wrong ROS type.
    """
    descriptions = descriptions or {}
    ranges = ranges or {}
    fields = config_fields(type(config_instance))
    unknown = (set(descriptions) | set(ranges)) - {field.name for field in fields}
    if unknown:
        raise ValueError(
            f"descriptions/ranges name no field of {type(config_instance).__name__}: {sorted(unknown)}"
        )
    declared: dict[str, Any] = {}
    for field in fields:
        full_name = parameter_name(prefix, field.name)
        descriptor = _descriptor(
            field,
            full_name,
            descriptions.get(field.name, field.description),
            ranges.get(field.name, field.value_range),
            read_only,
        )
        default = _to_parameter_value(field, _value_at(config_instance, field.path))
        value_range = ranges.get(field.name, field.value_range)
        if value_range is not None and not value_range[0] <= default <= value_range[1]:
            raise ValueError(f"{full_name}: default {default!r} lies outside its range {value_range}")
        try:
            declared[full_name] = node.declare_parameter(full_name, default, descriptor).value
        except InvalidParameterValueException as error:  # an override outside the ROS range
            raise ValueError(str(error)) from error
    return config_from_parameters(type(config_instance), config_instance, declared, prefix)


class ConfigParameters(Generic[ConfigT]):
    """Keep one frozen config in step with the node parameters ``<prefix>.<field>``.

    On construction the parameters are declared and the initial config is built from them. Afterwards each
    ``set_parameters`` request touching this prefix is validated by building the whole new config
    (:func:`config_from_parameters`); a failure rejects the request with the ``ValueError`` message as
    ``reason``; a success replaces :attr:`config` by the new instance once ROS has stored the values, and
    calls ``on_change(new_config)`` if given. Readers take :attr:`config` once per step, so a step sees one
    consistent config.

    Args:
        node: The node owning the parameters.
        prefix: Parameter name prefix without trailing dot (``""`` for none).
        default: Default config (values not overridden at start-up).
        descriptions: See :func:`declare_config_parameters`.
        ranges: See :func:`declare_config_parameters`.
        read_only: See :func:`declare_config_parameters`.
        on_change: Called with the new config after every accepted change.
        check: Extra validation of a candidate config (e.g. against another node parameter); raises
            ``ValueError`` to reject it. Applied to the initial config too.

    Raises:
        ValueError: the initial (declared) values do not form a valid config.
    """

    def __init__(
        self,
        node: Node,
        prefix: str,
        default: ConfigT,
        *,
        descriptions: Mapping[str, str] | None = None,
        ranges: Mapping[str, tuple[float, float]] | None = None,
        read_only: bool = False,
        on_change: Callable[[ConfigT], None] | None = None,
        check: Callable[[ConfigT], None] | None = None,
    ) -> None:
        self._config_cls: type[ConfigT] = type(default)
        self._prefix = prefix
        self._on_change = on_change
        self._check = check
        self._config: ConfigT = declare_config_parameters(
            node, prefix, default, descriptions=descriptions, ranges=ranges, read_only=read_only
        )
        if check is not None:
            check(self._config)
        fields = config_fields(self._config_cls)
        self._names = frozenset(parameter_name(prefix, field.name) for field in fields)
        # Registered after the declarations: declare_parameter runs these callbacks one parameter at a time.
        node.add_on_set_parameters_callback(self._validate)
        node.add_post_set_parameters_callback(self._commit)

    @property
    def config(self) -> ConfigT:
        """The current config (a frozen instance; replaced whole on every accepted change)."""
        return self._config

    @property
    def prefix(self) -> str:
        """Parameter name prefix (without trailing dot)."""
        return self._prefix

    @property
    def parameter_names(self) -> frozenset[str]:
        """Full names of the parameters this binding owns."""
        return self._names

    def validate(self, config: ConfigT) -> None:
        """Run the extra ``check`` on ``config`` (dataclass validation has already happened).

        Raises:
            ValueError: the check rejects it.
        """
        if self._check is not None:
            self._check(config)

    def _overrides(self, parameters: Sequence[Parameter]) -> dict[str, Any]:
        return {p.name: p.value for p in parameters if p.name in self._names}

    def _validate(self, parameters: list[Parameter]) -> SetParametersResult:
        overrides = self._overrides(parameters)
        if overrides:
            try:
                candidate = config_from_parameters(self._config_cls, self._config, overrides, self._prefix)
                if self._check is not None:
                    self._check(candidate)
            except ValueError as error:
                return SetParametersResult(successful=False, reason=str(error))
        return SetParametersResult(successful=True)

    def _commit(self, parameters: list[Parameter]) -> None:
        overrides = self._overrides(parameters)
        if not overrides:
            return
        # Cannot fail: _validate built the same config from the same values moments ago.
        self._config = config_from_parameters(self._config_cls, self._config, overrides, self._prefix)
        if self._on_change is not None:
            self._on_change(self._config)
