"""A config's parameters as Markdown table rows: name, type, default, range, meaning (docs/NODES.md)."""

from __future__ import annotations

from typing import Any

from smm_schema.fields import ConfigField, FieldKind, config_fields, parameter_name, value_at

__all__ = ["TABLE_HEAD", "parameter_rows"]

TABLE_HEAD = "| parameter | type | default | range | meaning |\n|---|---|---|---|---|"
"""The head of a parameter table (two lines)."""

_TYPES = {
    FieldKind.DOUBLE: "double",
    FieldKind.INTEGER: "integer",
    FieldKind.BOOL: "bool",
    FieldKind.STRING: "string",
    FieldKind.DOUBLE_ARRAY: "double",
    FieldKind.INTEGER_ARRAY: "integer",
}


def _number(value: Any) -> str:
    return str(value) if isinstance(value, int) else f"{value:g}"


def _default(field: ConfigField, value: Any) -> str:
    if field.kind in (FieldKind.DOUBLE_ARRAY, FieldKind.INTEGER_ARRAY):
        return "[" + ", ".join(_number(v) for v in value) + "]"
    if field.kind is FieldKind.BOOL:
        return "true" if value else "false"
    if field.kind is FieldKind.STRING:
        return str(value) if value else '""'
    return _number(value)


def _type(field: ConfigField) -> str:
    if field.kind in (FieldKind.DOUBLE_ARRAY, FieldKind.INTEGER_ARRAY):
        return f"{_TYPES[field.kind]}[{field.length or ''}]"
    return _TYPES[field.kind]


def _range(field: ConfigField) -> str:
    if field.choices:
        return ", ".join(f'"{choice}"' for choice in field.choices)
    if field.value_range is None:
        return ""
    each = "each " if field.kind in (FieldKind.DOUBLE_ARRAY, FieldKind.INTEGER_ARRAY) else ""
    return each + field.value_range.requirement()


def _cell(text: str) -> str:
    return text.replace("|", "\\|")


def parameter_rows(prefix: str, config: object, *, read_only: bool = False, note: str = "") -> list[str]:
    """One table row per leaf field of ``config`` (its values as defaults), named ``<prefix>.<field>``.

    Args:
        prefix: Parameter name prefix ("" for none).
        config: A config dataclass instance.
        read_only: The parameters are settable at start-up only (said in the meaning).
        note: Put in italics before each meaning (e.g. when the node declares them).
    """
    rows = []
    for field in config_fields(type(config)):
        meaning = " ".join(
            part
            for part in (f"*{note}*" if note else "", field.description, "Read-only." if read_only else "")
            if part
        )
        cells = (
            f"`{parameter_name(prefix, field.name)}`",
            _type(field),
            _default(field, value_at(config, field.path)),
            _range(field),
            meaning,
        )
        rows.append("| " + " | ".join(_cell(cell) for cell in cells) + " |")
    return rows
