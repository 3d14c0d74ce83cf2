"""``smm-bag rerun``: the pure control chain offline on a bag's measurements, with other gains.

``ControlChain`` (no ROS) steps through the recorded measurements, applied torques and references with
gains from parameter files over the run manifest's over the defaults; its commands and estimates are set
beside the recorded ones. See docs/BAGS.md, "smm-bag" and "Rerun across machines".
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from smm_controller.chain import build_chain, make_law
from smm_controller.laws import law_names, law_table
from smm_node_runtime.parameter_check import UnknownParameterError as UnknownNameError
from smm_node_runtime.parameter_check import check_parameters
from smm_node_runtime.parameter_files import (
    ParameterFileError,
    node_key_matches,
    parameters_for,
    read_parameter_file,
)
from smm_schema.fields import config_from_parameters

from smm_analysis.errors import ParamsFileError, UnknownParameterError
from smm_analysis.runs.recorded import RecordedRun
from smm_controller import (
    ControlChain,
    FLESOConfig,
    FPDESOConfig,
    TrackingDifferentiatorConfig,
)
from smm_dynamics import SMMParameters

__all__ = [
    "APPLIED_FROM_COMMANDS",
    "APPLIED_FROM_EFFORT",
    "ChainSettings",
    "ChainStepper",
    "RerunResult",
    "chain_settings",
    "read_params_files",
    "rerun",
]

FloatArray = NDArray[np.float64]

# Parameter prefixes of controller_node, fleso_node and td_node (docs/NODES.md).
TD_PREFIX = "td"
FLESO_PREFIX = "fleso"
MODEL_PREFIX = "model"
NAMESPACE = "smm"
"""The graph's namespace (``smm_bringup.graph_nodes.NAMESPACE``)."""
CONTROLLER_NODE, TD_NODE, FLESO_NODE = "controller_node", "td_node", "fleso_node"
CHAIN_NODES = (CONTROLLER_NODE, TD_NODE, FLESO_NODE)
"""The graph's names of the chain's nodes (``smm_bringup.graph_nodes``; each node module's ``NODE_NAME``)."""
_CHAIN_PREFIXES: dict[str, frozenset[str] | None] = {
    TD_NODE: frozenset({TD_PREFIX}),
    FLESO_NODE: frozenset({FLESO_PREFIX, MODEL_PREFIX}),
    CONTROLLER_NODE: None,  # all of them, applied last
}
"""Per chain node, the parameter prefixes taken from it (None: every parameter), in the order applied."""


@dataclass(frozen=True)
class ChainSettings:
    """Everything that defines a chain: law name and gains, nominal model, TD and FLESO parameters."""

    algorithm: str
    law: Any
    model: SMMParameters
    td: TrackingDifferentiatorConfig
    fleso: FLESOConfig

    def build(self) -> ControlChain:
        """A fresh chain, as the graph's (:func:`smm_controller.chain.build_chain`)."""
        law = make_law(self.law, self.model)
        return build_chain(self.algorithm, self.model, law=law, td=self.td, fleso=self.fleso)

    @property
    def flip_size(self) -> tuple[float, float]:
        """Per joint, what a last-bit flip of the robust term's sign can move one step's torque by (N m).

        2 b_d for FPDESO's pure sign (boundary layer 0), 0 where the law is continuous.
        """
        if not isinstance(self.law, FPDESOConfig):
            return (0.0, 0.0)
        gain, layer = self.law.robust_gain, self.law.boundary_layer
        return (
            2.0 * gain[0] if layer[0] == 0.0 else 0.0,
            2.0 * gain[1] if layer[1] == 0.0 else 0.0,
        )


def read_params_files(paths: Sequence[Path], namespace: str = NAMESPACE) -> dict[str, Any]:
    """Flat ``{parameter: value}`` the chain runs with, from ROS parameter files read as rcl does.

    The files are read as ``smm-launch`` reads them for the graph's nodes (:data:`CHAIN_NODES` under
    ``/<namespace>``; later files win, ``/**`` and other wildcard keys before exact keys):
    ``controller_node``'s parameters, which it runs the fused chain with, over ``td_node``'s ``td.*`` and
    ``fleso_node``'s ``fleso.*`` and ``model.*`` (files written for the split graph). Sections and names
    are checked as ``smm-launch`` checks them (:func:`smm_node_runtime.parameter_check.check_parameters`).

    Raises:
        ParamsFileError: Unreadable file, not a ROS parameter file, or no section for the chain's nodes.
        UnknownParameterError: A section reaches no node of the stack under ``/<namespace>``, or sets a name
            that no node it reaches declares.
    """
    prefix = f"/{namespace.strip('/')}" if namespace.strip("/") else ""
    names = {node: f"{prefix}/{node}" for node in CHAIN_NODES}
    per_node: dict[str, dict[str, Any]] = {node: {} for node in CHAIN_NODES}
    for path in paths:
        try:
            sections = read_parameter_file(path)
        except ParameterFileError as error:
            raise ParamsFileError(str(error)) from None
        try:
            check_parameters([path], (), {}, namespace)
        except UnknownNameError as error:
            raise UnknownParameterError(str(error)) from None
        if not any(node_key_matches(key, name) for key in sections for name in names.values()):
            keys = ", ".join(sections) or "none"
            raise ParamsFileError(f"{path} has no section for {', '.join(names.values())} (its keys: {keys})")
        for node, name in names.items():
            per_node[node].update(parameters_for(sections, name))
    merged: dict[str, Any] = {}
    for node, prefixes in _CHAIN_PREFIXES.items():
        merged.update(
            (name, value)
            for name, value in per_node[node].items()
            if prefixes is None or name.partition(".")[0] in prefixes
        )
    return merged


def chain_settings(parameters: Mapping[str, Any], algorithm: str = "fpdeso") -> ChainSettings:
    """Chain settings from flat parameters over the defaults.

    Args:
        parameters: ``{name: value}`` in controller_node's names; ``algorithm`` overrides ``algorithm``.
        algorithm: Law when ``parameters`` has no ``algorithm``.

    Raises:
        ParamsFileError: Unknown algorithm or a value the configs reject (the message says which).
    """
    name = str(parameters.get("algorithm", algorithm))
    if name not in law_table():
        raise ParamsFileError(f"algorithm must be one of {', '.join(law_names())}, got {name!r}")
    try:
        law_type = law_table()[name].config
        return ChainSettings(
            algorithm=name,
            law=config_from_parameters(law_type, law_type(), parameters, name),
            model=config_from_parameters(SMMParameters, SMMParameters(), parameters, MODEL_PREFIX),
            td=config_from_parameters(
                TrackingDifferentiatorConfig, TrackingDifferentiatorConfig(), parameters, TD_PREFIX
            ),
            fleso=config_from_parameters(FLESOConfig, FLESOConfig(), parameters, FLESO_PREFIX),
        )
    except (ValueError, TypeError) as error:
        raise ParamsFileError(f"invalid gains: {error}") from None


APPLIED_FROM_EFFORT = "recorded effort"
APPLIED_FROM_COMMANDS = "recorded commands (no effort in the bag)"
"""Where the applied torque comes from (``applied_torque_from``)."""


class ChainStepper:
    """The chain stepped over consecutive recorded steps, block by block, as one run.

    The applied torque is the recorded effort, or (``from_effort`` False) the previous step's recorded
    command, zero at the first step; the last command is carried to the next block.

    Args:
        settings: The chain to run.
        dt: Control period (s).
        from_effort: Whether the bag has the effort at every step.
    """

    def __init__(self, settings: ChainSettings, dt: float, *, from_effort: bool) -> None:
        self.chain = settings.build()
        self.dt = dt
        self.from_effort = from_effort
        self.applied_source = APPLIED_FROM_EFFORT if from_effort else APPLIED_FROM_COMMANDS
        self._previous_command = np.zeros((1, 2))

    def step(
        self,
        measured: FloatArray,
        applied: FloatArray | None,
        recorded_command: FloatArray,
        reference: FloatArray,
    ) -> tuple[FloatArray, FloatArray]:
        """Steps the chain over the next steps.

        Args:
            measured: Measured positions (rad), shape (n, 2).
            applied: Recorded effort (N m), shape (n, 2) (ignored unless ``from_effort``).
            recorded_command: Recorded commands (N m), shape (n, 2).
            reference: q_d, q_d', q_d'' (rad, rad/s, rad/s^2), shape (n, 3, 2).

        Returns:
            Offline commands and disturbance estimates (N m), each shape (n, 2).
        """
        if self.from_effort and applied is not None:
            rows = applied.tolist()
        else:
            rows = np.vstack([self._previous_command, recorded_command[:-1]]).tolist()
            self._previous_command = recorded_command[-1:].copy()
        steps = len(rows)
        command = np.empty((steps, 2))
        estimate = np.empty((steps, 2))
        chain, dt = self.chain, self.dt
        for k, (y, tau, r) in enumerate(zip(measured.tolist(), rows, reference.tolist(), strict=True)):
            command[k] = chain.step_floats((y[0], y[1]), (tau[0], tau[1]), r, dt)
            estimate[k] = chain.disturbance_estimate
        return command, estimate


@dataclass(frozen=True, eq=False)
class RerunResult:
    """The offline chain's outputs beside the recorded ones, at the recorded steps.

    Attributes:
        settings: The chain that ran.
        t_ns: Stamps (ns), shape (N,).
        command: Offline torque command (N m), shape (N, 2).
        recorded_command: Recorded torque command (N m), shape (N, 2).
        estimate: Offline disturbance estimate (N m), shape (N, 2) (zeros without FLESO).
        recorded_estimate: Recorded estimate, or None.
        applied_source: ``"recorded effort"`` or ``"recorded commands (no effort in the bag)"``.
    """

    settings: ChainSettings
    t_ns: NDArray[np.int64]
    command: FloatArray
    recorded_command: FloatArray
    estimate: FloatArray
    recorded_estimate: FloatArray | None
    applied_source: str

    @property
    def max_command_difference(self) -> float:
        """Max |offline - recorded| torque over steps and joints (N m)."""
        return float(np.max(np.abs(self.command - self.recorded_command)))


def rerun(run: RecordedRun, settings: ChainSettings) -> RerunResult:
    """Runs the chain over the recorded steps held in memory (``smm-bag rerun`` streams: ``rerun_stream``).

    Args:
        run: The recorded run.
        settings: The chain to run.

    Returns:
        Offline and recorded outputs side by side.
    """
    stepper = ChainStepper(
        settings, run.manifest.control_period_ns / 1e9, from_effort=run.applied_torque is not None
    )
    command, estimate = stepper.step(
        run.measured_position, run.applied_torque, run.command_torque, run.reference
    )
    return RerunResult(
        settings=settings,
        t_ns=run.t_ns,
        command=command,
        recorded_command=run.command_torque,
        estimate=estimate,
        recorded_estimate=run.disturbance_estimate,
        applied_source=stepper.applied_source,
    )
