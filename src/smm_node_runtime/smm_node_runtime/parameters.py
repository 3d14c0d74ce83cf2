"""Config dataclasses as ROS 2 parameters: descriptors, declaration, and one binding per node config.

Gives rclpy the schema of :mod:`smm_schema.fields`; a number field's range becomes the closed
``FloatingPointRange`` / ``IntegerRange`` (open ends and array elements in ``additional_constraints``,
checked by the config). :class:`ConfigParameters` declares, builds the initial config, and validates each
change as a whole new config, swapped only on success. docs/DESIGN.md, "Ranges of config fields";
docs/NODES.md, "Parameters".
"""

from __future__ import annotations

import dataclasses
import weakref
from collections.abc import Callable, Mapping, Sequence
from typing import Any, Generic, TypeVar

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
from smm_schema.fields import (
    ConfigField,
    FieldKind,
    config_fields,
    config_from_parameters,
    constraints,
    integer_span,
    parameter_name,
    parameter_value,
    value_at,
)

__all__ = [
    "ConfigParameters",
    "config_bindings",
    "declare_config_parameters",
    "parameter_descriptor",
]

ConfigT = TypeVar("ConfigT")

_PARAMETER_TYPES = {
    FieldKind.DOUBLE: ParameterType.PARAMETER_DOUBLE,
    FieldKind.INTEGER: ParameterType.PARAMETER_INTEGER,
    FieldKind.BOOL: ParameterType.PARAMETER_BOOL,
    FieldKind.STRING: ParameterType.PARAMETER_STRING,
    FieldKind.DOUBLE_ARRAY: ParameterType.PARAMETER_DOUBLE_ARRAY,
    FieldKind.INTEGER_ARRAY: ParameterType.PARAMETER_INTEGER_ARRAY,
}


_BINDINGS: weakref.WeakKeyDictionary[Node, list[ConfigParameters[Any]]] = weakref.WeakKeyDictionary()
"""Every node's :class:`ConfigParameters`, in the order it made them."""


def config_bindings(node: Node) -> tuple[ConfigParameters[Any], ...]:
    """The configs ``node`` mirrors as parameters (its :class:`ConfigParameters`), in the order made."""
    return tuple(_BINDINGS.get(node, ()))


def parameter_descriptor(field: ConfigField, full_name: str, read_only: bool = False) -> ParameterDescriptor:
    """The ROS descriptor of the parameter mirroring ``field``: type, description, range, constraints."""
    descriptor = ParameterDescriptor(
        name=full_name,
        type=_PARAMETER_TYPES[field.kind],
        description=field.description or field.name,
        additional_constraints=constraints(field),
        read_only=read_only,
    )
    value_range = field.value_range
    if value_range is None or value_range.unbounded:
        return descriptor
    if field.kind is FieldKind.DOUBLE:
        descriptor.floating_point_range = [
            FloatingPointRange(from_value=float(value_range.low), to_value=float(value_range.high), step=0.0)
        ]
    elif field.kind is FieldKind.INTEGER:
        first, last = integer_span(value_range)
        descriptor.integer_range = [IntegerRange(from_value=first, to_value=last, step=1)]
    return descriptor


def declare_config_parameters(
    node: Node,
    prefix: str,
    config_instance: ConfigT,
    *,
    descriptions: Mapping[str, str] | None = None,
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
        read_only: Declare the parameters read-only (settable only at start-up).

    Returns:
        The config built from the declared values.

    Raises:
        ValueError: the declared values do not form a valid config (message of the dataclass).
        rclpy.exceptions.InvalidParameterTypeException: an override has the wrong ROS type.
    """
    descriptions = descriptions or {}
    fields = config_fields(type(config_instance))
    unknown = set(descriptions) - {field.name for field in fields}
    if unknown:
        raise ValueError(f"descriptions name no field of {type(config_instance).__name__}: {sorted(unknown)}")
    declared: dict[str, Any] = {}
    for field in fields:
        full_name = parameter_name(prefix, field.name)
        described = field
        if field.name in descriptions:
            described = dataclasses.replace(field, description=descriptions[field.name])
        descriptor = parameter_descriptor(described, full_name, read_only)
        default = parameter_value(field, value_at(config_instance, field.path))
        try:
            declared[full_name] = node.declare_parameter(full_name, default, descriptor).value
        except InvalidParameterValueException as error:  # a default or an override outside the ROS range
            raise ValueError(str(error)) from error
    return config_from_parameters(type(config_instance), config_instance, declared, prefix)


class ConfigParameters(Generic[ConfigT]):
    """Keep one frozen config in step with the node parameters ``<prefix>.<field>``.

    On construction the parameters are declared and the initial config is built from them. Afterwards each
    ``set_parameters`` request touching this prefix is validated by building the whole new config
    (:func:`config_from_parameters`); a failure rejects the request with the ``ValueError`` message as
    ``reason``; a success replaces :attr:`config` by the new instance once ROS has stored the values, logs
    each changed value (``parameter <name>: <old> -> <new>``), and calls ``on_change(new_config)`` if given.
    Readers take :attr:`config` once per step, so a step sees one consistent config.

    Args:
        node: The node owning the parameters.
        prefix: Parameter name prefix without trailing dot (``""`` for none).
        default: Default config (values not overridden at start-up).
        descriptions: See :func:`declare_config_parameters`.
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
        read_only: bool = False,
        on_change: Callable[[ConfigT], None] | None = None,
        check: Callable[[ConfigT], None] | None = None,
    ) -> None:
        self._config_cls: type[ConfigT] = type(default)
        self._prefix = prefix
        self._default = default
        self._read_only = read_only
        self._on_change = on_change
        self._check = check
        self._config: ConfigT = declare_config_parameters(
            node, prefix, default, descriptions=descriptions, read_only=read_only
        )
        if check is not None:
            check(self._config)
        fields = config_fields(self._config_cls)
        self._names = frozenset(parameter_name(prefix, field.name) for field in fields)
        self._fields = {parameter_name(prefix, field.name): field for field in fields}
        self._log = node.get_logger()  # type: ignore[no-untyped-call]
        # Registered after the declarations: declare_parameter runs these callbacks one parameter at a time.
        node.add_on_set_parameters_callback(self._validate)
        node.add_post_set_parameters_callback(self._commit)
        _BINDINGS.setdefault(node, []).append(self)

    @property
    def config(self) -> ConfigT:
        """The current config (a frozen instance; replaced whole on every accepted change)."""
        return self._config

    @property
    def prefix(self) -> str:
        """Parameter name prefix (without trailing dot)."""
        return self._prefix

    @property
    def default(self) -> ConfigT:
        """The config the node offered as default (before its parameter overrides)."""
        return self._default

    @property
    def read_only(self) -> bool:
        """True when the parameters are settable only at start-up."""
        return self._read_only

    @property
    def fields(self) -> tuple[ConfigField, ...]:
        """The config's leaf fields, one per parameter (names relative to :attr:`prefix`)."""
        return config_fields(self._config_cls)

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
        old = self._config
        self._config = config_from_parameters(self._config_cls, old, overrides, self._prefix)
        for name in sorted(overrides):
            field = self._fields[name]
            before = parameter_value(field, value_at(old, field.path))
            after = parameter_value(field, value_at(self._config, field.path))
            if before != after:
                self._log.info(f"parameter {name}: {before!r} -> {after!r}")
        if self._on_change is not None:
            self._on_change(self._config)
