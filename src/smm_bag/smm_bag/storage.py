"""Where a bag's storage files are: a rosbag2 folder or a bare ``.mcap`` / ``.db3`` file, file compression.

MCAP and sqlite3 (``.db3``, rosbag2's default before Iron) are read; a ROS 1 bag is named and refused.
rosbag2's file compression (``compression_mode: file``) stores each file as ``<name>.mcap.zstd`` (or
``.db3.zstd``); its bytes are decompressed into a temporary file (never next to the bag) and read from there.
"""

from __future__ import annotations

import mmap
import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import zstandard

from smm_bag.errors import NotABagError, OtherStorageError
from smm_bag.metadata import METADATA_FILE, READABLE_STORAGE, BagMetadata, read_metadata

__all__ = [
    "MCAP_MAGIC",
    "BagLocation",
    "FileBytes",
    "is_file_compressed",
    "locate",
    "mapped_file",
    "other_storage",
    "plain_file",
]

MCAP_MAGIC = b"\x89MCAP0\r\n"
_SQLITE_MAGIC = b"SQLite format 3\x00"
_ROS1_MAGIC = b"#ROSBAG V"
_ZSTD_MAGIC = b"\x28\xb5\x2f\xfd"


@dataclass(frozen=True)
class BagLocation:
    """A bag on disk: the folder, its ``metadata.yaml`` (None for a bare file), its storage files and kind."""

    directory: Path
    metadata: BagMetadata | None
    files: tuple[Path, ...]
    storage: str = "mcap"

    @property
    def bare(self) -> bool:
        """True for a storage file given without its folder's ``metadata.yaml``."""
        return self.metadata is None


def other_storage(path: Path) -> str | None:
    """The storage a non-MCAP bag file uses (``sqlite3``, ``ROS 1 bag``), from its magic, or None."""
    try:
        with path.open("rb") as stream:
            head = stream.read(len(_SQLITE_MAGIC))
    except OSError:
        return None
    if head.startswith(_SQLITE_MAGIC):
        return "sqlite3"
    if head.startswith(_ROS1_MAGIC):
        return "ROS 1 bag"
    return None


def is_file_compressed(path: Path) -> bool:
    """True for a rosbag2 file-compressed storage file (``*.zstd``, zstd frame magic)."""
    return path.name.endswith(".zstd")


def _other_storage_error(path: Path, kind: str) -> OtherStorageError:
    return OtherStorageError(f"{path}: {kind} storage (smm-bag reads MCAP and sqlite3 bags)")


def _missing_metadata(path: Path) -> NotABagError | OtherStorageError:
    """No ``metadata.yaml``: what rebuilds it, for the storage files the folder holds."""
    names = sorted(item.name for item in path.iterdir() if item.is_file())
    if any(name.endswith((".mcap", ".mcap.zstd")) for name in names):
        return NotABagError(
            f"{path} has no {METADATA_FILE}, but holds MCAP files: `smm-bag repair {path}` rebuilds it "
            "from them (or give one .mcap file)"
        )
    db3 = [name for name in names if other_storage(path / name) == "sqlite3"]
    if db3:
        return NotABagError(
            f"{path} has no {METADATA_FILE}, but holds sqlite3 files: give one of them "
            f"(`smm-bag info {path / db3[0]}`), or rebuild it with `ros2 bag reindex {path} -s sqlite3`"
        )
    for name in names:
        kind = other_storage(path / name)
        if kind is not None:
            return _other_storage_error(path, kind)
    return NotABagError(f"{path} is not a rosbag2 bag: it has no {METADATA_FILE}")


def locate(path: Path) -> BagLocation:
    """The bag at ``path``: a rosbag2 folder, or one bare ``.mcap`` / ``.db3`` file (or its ``.zstd``).

    Raises:
        OtherStorageError: The bag uses another storage (ROS 1 ``.bag``, a storage plugin not read here).
        NotABagError: Neither a rosbag2 folder nor a storage file; a folder without ``metadata.yaml`` (the
            message says what rebuilds it).
        CorruptBagError: ``metadata.yaml`` is unreadable.
    """
    if path.is_file():
        kind = other_storage(path)
        if kind == "sqlite3" or (kind is None and path.name.endswith(".db3.zstd")):
            return BagLocation(path.parent, None, (path,), "sqlite3")
        if kind is not None:
            raise _other_storage_error(path, kind)
        if path.name == METADATA_FILE:
            return locate(path.parent)
        with path.open("rb") as stream:
            head = stream.read(len(MCAP_MAGIC))
        if head != MCAP_MAGIC and not head.startswith(_ZSTD_MAGIC):
            raise NotABagError(
                f"{path} is not a directory (a rosbag2 bag folder) nor an MCAP or sqlite3 file"
            )
        return BagLocation(path.parent, None, (path,))
    if not path.is_dir():
        raise NotABagError(
            f"{path} is not a directory (a rosbag2 bag is a folder with metadata.yaml) nor a file"
        )
    if not (path / METADATA_FILE).is_file():
        raise _missing_metadata(path)
    metadata = read_metadata(path)
    if metadata.storage_identifier not in READABLE_STORAGE:
        raise _other_storage_error(path, metadata.storage_identifier or "unnamed")
    if not metadata.files:
        raise NotABagError(f"{path}: metadata.yaml lists no storage file")
    files = tuple(path / info.path for info in metadata.files)
    return BagLocation(path, metadata, files, metadata.storage_identifier)


@dataclass(frozen=True)
class FileBytes:
    """A storage file's MCAP bytes (a read-only map) and whether decompression reached its end."""

    data: bytes
    complete: bool


@contextmanager
def _mapped(path: Path) -> Iterator[bytes]:
    with path.open("rb") as stream:
        if path.stat().st_size == 0:
            yield b""
            return
        with mmap.mmap(stream.fileno(), 0, access=mmap.ACCESS_READ) as data:
            yield data  # type: ignore[misc]


def _decompress(source: Path, target: Path) -> bool:
    """Decompresses the zstd file ``source`` into ``target``; False if it ends in a frame or is damaged."""
    complete = True
    with source.open("rb") as raw, target.open("wb") as out:
        decompressor = zstandard.ZstdDecompressor().decompressobj()
        try:
            while block := raw.read(1 << 20):
                while block:
                    out.write(decompressor.decompress(block))
                    block = decompressor.unused_data if decompressor.eof else b""
                    if decompressor.eof:
                        decompressor = zstandard.ZstdDecompressor().decompressobj()
                        complete = True
                    else:
                        complete = False
        except zstandard.ZstdError:
            complete = False
    return complete


@contextmanager
def plain_file(path: Path) -> Iterator[tuple[Path, bool]]:
    """A storage file's uncompressed path (a temporary copy if file-compressed) and whether it is complete."""
    if not is_file_compressed(path):
        yield path, True
        return
    suffix = Path(path.name.removesuffix(".zstd")).suffix
    handle, name = tempfile.mkstemp(prefix="smm-bag-", suffix=suffix)
    os.close(handle)
    temporary = Path(name)
    try:
        complete = _decompress(path, temporary)
        yield temporary, complete
    finally:
        temporary.unlink(missing_ok=True)


@contextmanager
def mapped_file(path: Path) -> Iterator[FileBytes]:
    """The MCAP bytes of a storage file, decompressed to a temporary file first if file-compressed."""
    with plain_file(path) as (plain, complete), _mapped(plain) as data:
        yield FileBytes(data, complete)
