"""The run manifest stored in a bag's ``custom_data``: what ran, with which parameters, on which plant."""

from __future__ import annotations

import subprocess
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from smm_bag.errors import CorruptBagError

__all__ = ["RunManifest", "git_describe"]

_PREFIX = "smm."


@dataclass(frozen=True)
class RunManifest:
    """What a recorded run was (every field optional: a bench run may not know a scenario or seed).

    Attributes:
        version: ``git describe`` of the stack that ran.
        scenario: Scenario name (``case2``, ...).
        seed: Noise seed of the simulated or emulated plant; None: unknown (an external board).
        plant: ``sim`` or ``hardware``.
        controller: Controller name (``fpdeso``, ``fpd``, ...).
        control_period_ns: Control period (ns).
        clock_mode: ``lockstep`` or ``realtime``.
        namespace: Namespace of the stack's topics.
        parameters: Every node's parameters at start, ``{node: {name: value}}``.
        parameters_unread: Nodes the recorder saw whose parameter service did not answer while recording.
        topics_skipped: Topics the recorder did not record, their type not being installed (topic -> type).
    """

    version: str = ""
    scenario: str = ""
    seed: int | None = None
    plant: str = ""
    controller: str = ""
    control_period_ns: int = 1_000_000
    clock_mode: str = ""
    namespace: str = "smm"
    parameters: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    parameters_unread: tuple[str, ...] = ()
    topics_skipped: Mapping[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.plant not in ("", "sim", "hardware"):
            raise ValueError(f"plant must be 'sim' or 'hardware', got {self.plant!r}")
        if self.control_period_ns <= 0:
            raise ValueError(f"control_period_ns must be > 0, got {self.control_period_ns}")

    def to_custom_data(self) -> dict[str, str]:
        """``custom_data`` entries (all strings; ``smm.parameters`` is YAML)."""
        data = {
            "smm.version": self.version,
            "smm.scenario": self.scenario,
            "smm.seed": "" if self.seed is None else str(self.seed),
            "smm.plant": self.plant,
            "smm.controller": self.controller,
            "smm.control_period_ns": str(self.control_period_ns),
            "smm.clock_mode": self.clock_mode,
            "smm.namespace": self.namespace,
            "smm.parameters": yaml.safe_dump(
                {node: dict(values) for node, values in self.parameters.items()}, sort_keys=True
            ),
        }
        if self.parameters_unread:
            data["smm.parameters_unread"] = yaml.safe_dump(list(self.parameters_unread))
        if self.topics_skipped:
            data["smm.topics_skipped"] = yaml.safe_dump(dict(self.topics_skipped), sort_keys=True)
        return data

    @classmethod
    def from_custom_data(cls, data: Mapping[str, str]) -> RunManifest:
        """The manifest of a bag (defaults for missing entries).

        Raises:
            CorruptBagError: An entry is malformed.
        """
        try:
            seed_text = data.get("smm.seed", "")
            parameters = yaml.safe_load(data.get("smm.parameters", "")) or {}
            if not isinstance(parameters, dict):
                raise ValueError("smm.parameters is not a mapping")
            unread = yaml.safe_load(data.get("smm.parameters_unread", "")) or []
            if not isinstance(unread, list) or not all(isinstance(node, str) for node in unread):
                raise ValueError("smm.parameters_unread is not a list of node names")
            skipped = yaml.safe_load(data.get("smm.topics_skipped", "")) or {}
            if not isinstance(skipped, dict) or not all(isinstance(v, str) for v in skipped.values()):
                raise ValueError("smm.topics_skipped is not a mapping of topics to types")
            return cls(
                version=data.get("smm.version", ""),
                scenario=data.get("smm.scenario", ""),
                seed=int(seed_text) if seed_text else None,
                plant=data.get("smm.plant", ""),
                controller=data.get("smm.controller", ""),
                control_period_ns=int(data.get("smm.control_period_ns", "1000000")),
                clock_mode=data.get("smm.clock_mode", ""),
                namespace=data.get("smm.namespace", "smm"),
                parameters=parameters,
                parameters_unread=tuple(unread),
                topics_skipped={str(topic): kind for topic, kind in skipped.items()},
            )
        except (ValueError, yaml.YAMLError) as error:
            raise CorruptBagError(f"malformed run manifest in custom_data: {error}") from None

    def topic(self, relative: str) -> str:
        """Absolute name of a stack topic under this run's namespace."""
        if relative.startswith("/"):
            return relative
        stripped = self.namespace.strip("/")
        return f"/{stripped}/{relative}" if stripped else f"/{relative}"


def git_describe(directory: Path | None = None) -> str:
    """``git describe --always --dirty --tags`` of ``directory`` (default: this package's checkout), or ""."""
    where = directory if directory is not None else Path(__file__).resolve().parent
    try:
        result = subprocess.run(
            ["git", "describe", "--always", "--dirty", "--tags"],
            cwd=where,
            capture_output=True,
            text=True,
            timeout=10,
            check=False,
        )
    except (OSError, subprocess.SubprocessError):
        return ""
    return result.stdout.strip() if result.returncode == 0 else ""
