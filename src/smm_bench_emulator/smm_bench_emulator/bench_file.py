"""The bench description: a YAML file of the emulator's whole bench, read against its schema (docs/BENCH.md).

Its ``plant`` section has the fields of ``smm_sim_node``'s plant parameters (:class:`smm_sim.config.
PlantParameters`, same names, units and ranges); every other key is a field of
:class:`~smm_bench_emulator.bench.BenchSettings`. A field left out keeps the emulator's default
(:func:`default_bench`); an unknown key is refused with the closest known name.
"""

from __future__ import annotations

import dataclasses
import difflib
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Final

import yaml
from smm_schema.fields import ConfigField, config_fields, config_from_parameters, parameter_name
from smm_schema.tables import TABLE_HEAD, parameter_rows
from smm_sim.plant import PAPER_VALVE_RESPONSE_TIMES, valve_time_constants_from_response_times

from smm_bench_emulator.bench import BenchSettings
from smm_bench_emulator.board import BoardConfig
from smm_sim.config import PlantParameters

__all__ = [
    "PLANT",
    "BenchFileError",
    "bench_from_document",
    "bench_table",
    "board_config",
    "default_bench",
    "default_plant",
    "load_bench_file",
]

PLANT: Final[str] = "plant"
"""The section holding the plant's fields."""
_NOT_ON_THE_BENCH: Final[dict[str, str]] = {
    f"{PLANT}.initial_position": "the emulated bench starts at rest at q = 0, as a board at power-on",
}


class BenchFileError(ValueError):
    """A bench description that cannot be read or is not a valid bench (the message says which field)."""


def default_plant() -> PlantParameters:
    """The plant the emulator runs without a file: 2**20 counts per revolution, the paper's valve lag."""
    return PlantParameters(
        encoder_counts_per_rev=1 << 20,
        valve_time_constants=valve_time_constants_from_response_times(*PAPER_VALVE_RESPONSE_TIMES),
    )


def board_config(plant: PlantParameters, settings: BenchSettings) -> BoardConfig:
    """The board's configuration of a plant and the bench's other truths."""
    values = {item.name: getattr(settings, item.name) for item in dataclasses.fields(BenchSettings)}
    return BoardConfig(plant=plant.plant_config, **values)


def default_bench() -> BoardConfig:
    """The bench the emulator runs without a file (and the value of every field a file leaves out)."""
    return board_config(default_plant(), BenchSettings())


def _fields() -> dict[str, ConfigField]:
    plant = {
        name: item
        for item in config_fields(PlantParameters)
        if (name := parameter_name(PLANT, item.name)) not in _NOT_ON_THE_BENCH
    }
    return {**plant, **{item.name: item for item in config_fields(BenchSettings)}}


def _flatten(prefix: str, values: Mapping[Any, Any], out: dict[str, Any]) -> None:
    for key, value in values.items():
        name = parameter_name(prefix, str(key))
        if isinstance(value, Mapping):
            _flatten(name, value, out)
        else:
            out[name] = value


def bench_from_document(document: object, where: str = "bench description") -> BoardConfig:
    """The bench a parsed bench description (a mapping, or None for an empty file) describes.

    Raises:
        BenchFileError: Not a mapping, an unknown key (with the closest known name), or a field's value
            refused by its type or range (the message names the field).
    """
    if document is None:
        document = {}
    if not isinstance(document, Mapping):
        raise BenchFileError(f"{where}: must map field names to values, got {type(document).__name__}")
    values: dict[str, Any] = {}
    _flatten("", document, values)
    known = _fields()
    for name in values:
        if name in _NOT_ON_THE_BENCH:
            raise BenchFileError(f"{where}: {name} is not a bench field: {_NOT_ON_THE_BENCH[name]}")
        if name not in known:
            close = difflib.get_close_matches(name, list(known), n=1)
            hint = f"; did you mean {close[0]!r}?" if close else f"; known: {', '.join(known)}"
            raise BenchFileError(f"{where}: unknown field {name!r}{hint}")
    try:
        plant = config_from_parameters(PlantParameters, default_plant(), values, prefix=PLANT)
        settings = config_from_parameters(BenchSettings, BenchSettings(), values)
        return board_config(plant, settings)
    except ValueError as error:
        raise BenchFileError(f"{where}: {error}") from error


def load_bench_file(path: str | Path) -> BoardConfig:
    """The bench a bench description file describes.

    Raises:
        BenchFileError: The file is missing, is not YAML, or does not describe a valid bench.
    """
    try:
        document = yaml.safe_load(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as error:
        raise BenchFileError(f"cannot read bench file {path}: {error}") from error
    except yaml.YAMLError as error:
        raise BenchFileError(f"bench file {path} is not valid YAML: {error}") from error
    return bench_from_document(document, f"bench file {path}")


def bench_table() -> str:
    """The table of every field of a bench description with its default (docs/BENCH.md), newline-ended."""
    rows = parameter_rows(PLANT, default_plant()) + parameter_rows("", BenchSettings())
    hidden = tuple(f"| `{name}` |" for name in _NOT_ON_THE_BENCH)
    rows = [row for row in rows if not row.startswith(hidden)]
    return "\n".join([TABLE_HEAD.replace("| parameter |", "| field |"), *rows]) + "\n"
