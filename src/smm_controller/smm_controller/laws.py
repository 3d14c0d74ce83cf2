"""The table of control laws: the four of the paper and those other packages register (one row per law).

A package adds a law with an entry point of group ``smm_controller.laws`` naming a :class:`Law`; every
place that lists, builds or reconfigures laws reads this table (docs/DESIGN.md, "Extending").
"""

from __future__ import annotations

import functools
import importlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from importlib.metadata import entry_points
from types import MappingProxyType
from typing import Any, Final, Generic, TypeVar

from smm_controller.baselines import (
    FPDConfig,
    FPDController,
    NPDConfig,
    NPDController,
    PIDConfig,
    PIDController,
)
from smm_controller.fpdeso import FPDESOConfig, FPDESOController
from smm_controller.torque_law import TorqueLaw
from smm_dynamics import SMMParameters

__all__ = [
    "LAW_GROUP",
    "PAPER_LAWS",
    "Law",
    "UnknownLawError",
    "batched_twin",
    "get_law",
    "law_for_config",
    "law_names",
    "law_table",
]

LAW_GROUP: Final[str] = "smm_controller.laws"
"""Entry-point group through which other packages add laws (each entry point names a :class:`Law`)."""

ConfigT = TypeVar("ConfigT")
LawT = TypeVar("LawT", bound=TorqueLaw)


class UnknownLawError(ValueError):
    """A law name or config type the table does not hold (the message lists the known names)."""


@dataclass(frozen=True)
class Law(Generic[ConfigT, LawT]):
    """One row of the table: what the stack needs to know of a control law.

    Attributes:
        name: The law's name (``algorithm`` value, parameter prefix ``<name>.<field>``): a Python identifier.
        config: Its frozen config dataclass; ``config()`` gives the default gains.
        build: ``build(config, model)``: a fresh law (``model``: the nominal model, for laws that use it).
        reconfigure: ``reconfigure(law, config, model)``: new gains/model for a running law, state kept.
        uses_disturbance_estimate: True when the chain runs the FLESO before it (its xi~ reaches the law).
        uses_model: True when the law's gains depend on the nominal model (``model.*`` reconfigures it).
        batched: ``"module:attribute"`` of its batched twin (``twin(configs, batch_model)``, for sweeps),
            or None when it has none.
        label: Name in reports and plots.
    """

    name: str
    config: type[ConfigT]
    build: Callable[[ConfigT, SMMParameters], LawT]
    reconfigure: Callable[[LawT, ConfigT, SMMParameters], None]
    uses_disturbance_estimate: bool = False
    uses_model: bool = False
    batched: str | None = None
    label: str = ""

    def __post_init__(self) -> None:
        if not (isinstance(self.name, str) and self.name.isidentifier()):
            raise ValueError(f"a law's name must be a Python identifier, got {self.name!r}")
        if not isinstance(self.config, type):
            raise ValueError(f"law {self.name!r}: config must be a config class, got {self.config!r}")
        if self.batched is not None and ":" not in self.batched:
            raise ValueError(f"law {self.name!r}: batched must be 'module:attribute', got {self.batched!r}")

    @property
    def display(self) -> str:
        """The label, or the name when it has none."""
        return self.label or self.name


def _reconfigure_fpdeso(law: FPDESOController, config: FPDESOConfig, model: SMMParameters) -> None:
    law.reconfigure(config, params=model)


def _reconfigure_baseline(law: Any, config: Any, _model: SMMParameters) -> None:
    law.reconfigure(config)  # the baselines use no model


_BUILT_IN: Final[tuple[Law[Any, Any], ...]] = (
    Law(
        "fpdeso",
        FPDESOConfig,
        FPDESOController,
        _reconfigure_fpdeso,
        uses_disturbance_estimate=True,
        uses_model=True,
        batched="smm_analysis.batch.chain:BatchFPDESO",
        label="FPDESO",
    ),
    Law(
        "fpd",
        FPDConfig,
        lambda config, _model: FPDController(config),
        _reconfigure_baseline,
        batched="smm_analysis.batch.chain:BatchFPD",
        label="FPD",
    ),
    Law(
        "pid",
        PIDConfig,
        lambda config, _model: PIDController(config),
        _reconfigure_baseline,
        batched="smm_analysis.batch.chain:BatchPID",
        label="PID",
    ),
    Law(
        "npd",
        NPDConfig,
        lambda config, _model: NPDController(config),
        _reconfigure_baseline,
        batched="smm_analysis.batch.chain:BatchNPD",
        label="NPD",
    ),
)


PAPER_LAWS: Final[tuple[str, ...]] = tuple(law.name for law in _BUILT_IN)
"""The paper's laws, FPDESO first, then its baselines (reproduction and its claims compare these)."""


@functools.cache
def law_table() -> Mapping[str, Law[Any, Any]]:
    """Every law by name: the built-in four in the paper's order, then the registered ones by name.

    Read once per process (``law_table.cache_clear()`` reads the entry points again).

    Raises:
        ValueError: A registered entry point does not load, is not a :class:`Law`, or reuses a name or a
            config type (the message names the entry point).
    """
    table: dict[str, Law[Any, Any]] = {law.name: law for law in _BUILT_IN}
    for point in sorted(entry_points(group=LAW_GROUP), key=lambda p: p.name):
        where = f"entry point {point.name!r} ({point.value}) of group {LAW_GROUP!r}"
        try:
            law = point.load()
        except Exception as error:
            raise ValueError(f"{where} does not load: {type(error).__name__}: {error}") from error
        if not isinstance(law, Law):
            raise ValueError(f"{where} names {type(law).__name__}, not a smm_controller.laws.Law")
        if law.name in table:
            raise ValueError(f"{where}: law name {law.name!r} is taken")
        if any(other.config is law.config for other in table.values()):
            raise ValueError(f"{where}: config type {law.config.__name__} is another law's")
        table[law.name] = law
    return MappingProxyType(table)


def law_names() -> tuple[str, ...]:
    """Names of every law in the table, in its order."""
    return tuple(law_table())


def get_law(name: str) -> Law[Any, Any]:
    """The row of law ``name``.

    Raises:
        UnknownLawError: No law has this name.
    """
    law = law_table().get(name)
    if law is None:
        raise UnknownLawError(f"unknown law {name!r}; known: {', '.join(law_names())}")
    return law


def law_for_config(config: object) -> Law[Any, Any]:
    """The row whose config type ``config`` is.

    Raises:
        UnknownLawError: No law has this config type.
    """
    for law in law_table().values():
        if type(config) is law.config:
            return law
    raise UnknownLawError(f"{type(config).__name__} is the config of no law; known: {', '.join(law_names())}")


def batched_twin(law: Law[Any, Any]) -> Callable[..., Any]:
    """The batched twin of ``law`` (imported on first use: it lives in a package above this one).

    Raises:
        UnknownLawError: The law has no batched twin.
    """
    if law.batched is None:
        raise UnknownLawError(f"law {law.name!r} has no batched twin (sweeps need one)")
    module, _, attribute = law.batched.partition(":")
    twin: Callable[..., Any] = getattr(importlib.import_module(module), attribute)
    return twin
