"""Message definitions as rosbag2 stores them: the full ros2msg text and the RIHS01 type hash.

The text is built like rosbag2_cpp's ``LocalMessageDefinitionSource`` (Jazzy): the ``.msg`` file of the type,
then for each dependency (sorted, each once, depth first) a line of 80 ``=``, ``MSG: pkg/Type`` and its
``.msg`` text. The files come from the installed interface packages (``share/<pkg>/msg``); the type hash
from the ``.json`` type description next to them. rosbags' type store is the fallback when a package's
share directory is missing.
"""

from __future__ import annotations

import functools
import importlib.util
import json
import os
import re
import sys
from dataclasses import dataclass
from pathlib import Path

from smm_bag.errors import UnknownTypeError

__all__ = ["MessageDefinition", "message_definition", "normalise_type"]

_DELIMITER = "=" * 80 + "\n"
_PACKAGE_TYPENAME = re.compile(r"^([a-zA-Z0-9_]+)/(?:msg/|srv/)?([a-zA-Z0-9_]+)$")
_MSG_FIELD_TYPE = re.compile(r"(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+")
_PRIMITIVES = frozenset(
    [
        "bool",
        "byte",
        "char",
        "float32",
        "float64",
        "int8",
        "uint8",
        "int16",
        "uint16",
        "int32",
        "uint32",
        "int64",
        "uint64",
        "string",
    ]
)


@dataclass(frozen=True)
class MessageDefinition:
    """What a bag stores about a message type.

    Attributes:
        type: Type name ``pkg/msg/Type``.
        encoding: Schema encoding, ``ros2msg``.
        text: Full concatenated definition.
        type_hash: ``RIHS01_<hex>`` (empty if unknown).
    """

    type: str
    encoding: str
    text: str
    type_hash: str


def normalise_type(name: str) -> tuple[str, str]:
    """``(package, Type)`` of ``pkg/Type`` or ``pkg/msg/Type``.

    Raises:
        UnknownTypeError: Not a message type name.
    """
    match = _PACKAGE_TYPENAME.match(name)
    if match is None:
        raise UnknownTypeError(f"{name!r} is not a message type name (pkg/msg/Type)")
    return match.group(1), match.group(2)


def _share_dirs(package: str) -> list[Path]:
    """Candidate ``share/<package>`` folders: the ament index, this Python's prefix, the module's prefix."""
    candidates = [
        Path(prefix) / "share" / package
        for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep)
        if prefix
    ]
    candidates.append(Path(sys.prefix) / "share" / package)
    spec = importlib.util.find_spec(package)
    if spec is not None and spec.origin is not None:
        # <prefix>/lib/pythonX.Y/site-packages/<package>/__init__.py
        candidates.append(Path(spec.origin).resolve().parents[4] / "share" / package)
    return candidates


def _msg_file(package: str, name: str, suffix: str) -> Path | None:
    for share in _share_dirs(package):
        path = share / "msg" / f"{name}{suffix}"
        if path.is_file():
            return path
    return None


def _dependencies(text: str, package: str) -> list[str]:
    found: set[str] = set()
    for match in _MSG_FIELD_TYPE.finditer(text):
        field_type = match.group(1)
        if field_type in _PRIMITIVES:
            continue
        found.add(field_type if "/" in field_type else f"{package}/{field_type}")
    return sorted(found)


def _local_text(root: str) -> str | None:
    seen: set[str] = set()

    def append(type_name: str, depth: int) -> str:
        if depth <= 0:
            raise UnknownTypeError(f"reached the maximum recursion depth resolving {root}")
        package, name = normalise_type(type_name)
        path = _msg_file(package, name, ".msg")
        if path is None:
            raise FileNotFoundError(type_name)
        text = path.read_text(encoding="utf-8")
        result = text
        for dependency in _dependencies(text, package):
            if dependency not in seen:
                seen.add(dependency)
                result += "\n" + _DELIMITER + f"MSG: {dependency}\n" + append(dependency, depth - 1)
        return result

    try:
        return append(root, 50)
    except FileNotFoundError:
        return None


def _local_hash(package: str, name: str) -> str | None:
    path = _msg_file(package, name, ".json")
    if path is None:
        return None
    for entry in json.loads(path.read_text(encoding="utf-8")).get("type_hashes", []):
        if entry.get("type_name") == f"{package}/msg/{name}":
            return str(entry["hash_string"])
    return None


def _rosbags_definition(full_type: str) -> tuple[str, str]:
    from rosbags.typesys import Stores, get_typestore  # noqa: PLC0415

    store = get_typestore(Stores.ROS2_JAZZY)
    if full_type not in store.fielddefs:
        raise UnknownTypeError(f"no message definition known for {full_type}")
    text, _ = store.generate_msgdef(full_type, ros_version=2)
    return text, store.hash_rihs01(full_type)


@functools.cache
def message_definition(type_name: str) -> MessageDefinition:
    """The stored definition of a message type (``pkg/msg/Type`` or ``pkg/Type``).

    Raises:
        UnknownTypeError: Neither the installed packages nor rosbags' Jazzy type store know the type.
    """
    package, name = normalise_type(type_name)
    full_type = f"{package}/msg/{name}"
    text = _local_text(full_type)
    type_hash = _local_hash(package, name)
    if text is None or type_hash is None:
        fallback_text, fallback_hash = _rosbags_definition(full_type)
        text = fallback_text if text is None else text
        type_hash = fallback_hash if type_hash is None else type_hash
    return MessageDefinition(type=full_type, encoding="ros2msg", text=text, type_hash=type_hash)
