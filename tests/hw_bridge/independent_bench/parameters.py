"""The bridge's parameter file for the independent bench: its node ids, EDS files and units, nothing else."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
CANOPEN = "canopen"
"""The prefix of the CANopen link's bridge parameters: written once here."""


def _nested(flat: dict[str, Any]) -> dict[str, Any]:
    tree: dict[str, Any] = {}
    for name, value in flat.items():
        *parents, leaf = name.split(".")
        node = tree
        for parent in parents:
            node = node.setdefault(parent, {})
        node[leaf] = value
    return tree


def _yaml(tree: dict[str, Any], indent: int = 0) -> str:
    lines = []
    for key, value in tree.items():
        if isinstance(value, dict):
            lines.append(" " * indent + f"{key}:\n" + _yaml(value, indent + 2))
        else:
            lines.append(" " * indent + f"{key}: {json.dumps(value)}\n")
    return "".join(lines)


def bench_parameters(path: Path, group: str, port: int, **changes: Any) -> Path:
    """Writes the file at ``path`` for the bench on udp_multicast ``group``:``port``; ``changes``:
    ``canopen.*`` by their short name, ``bridge.*`` and ``link.*`` in full."""
    flat: dict[str, Any] = {
        "link.transport": "canopen",
        f"{CANOPEN}.channel": group,
        f"{CANOPEN}.port": port,
        f"{CANOPEN}.valve_node_ids": [21, 22],
        f"{CANOPEN}.encoder_node_ids": [31, 32],
        f"{CANOPEN}.valve_eds": str(HERE / "valve.eds"),
        f"{CANOPEN}.encoder_eds": str(HERE / "encoder.eds"),
        "bridge.valve.gain": [16384 / 12.0, 16384 / 12.0],  # +-16384 = +-100 % = +-12 N m on this bench
        "bridge.valve.code_limit": [16384, 16384],
        "bridge.valve.rate_limit": [16384 / 0.002, 16384 / 0.002],
        "bridge.valve.time_constants": [0.0, 0.0],  # 0x6301 is the spool measured: no lag model on top
        "bridge.encoder.counts_per_rev": [1 << 19, 1 << 19],
        "bridge.encoder.zero_offset": [100_000, 7],
        "bridge.encoder.direction": [1, -1],
    }
    flat.update(
        {f"{CANOPEN}.{k}" if not k.startswith(("bridge.", "link.")) else k: v for k, v in changes.items()}
    )
    path.write_text(_yaml({"/smm/hw_bridge_node": {"ros__parameters": _nested(flat)}}))
    return path
