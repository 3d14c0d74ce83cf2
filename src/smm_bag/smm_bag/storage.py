"""Where a bag's MCAP bytes are: a rosbag2 folder or a bare ``.mcap`` file, file compression, other storage.

rosbag2's file compression (``compression_mode: file``) stores each file as ``<name>.mcap.zstd``; its bytes
are decompressed into a temporary file (never next to the bag) and mapped from there.
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
from smm_bag.metadata import METADATA_FILE, BagMetadata, read_metadata

__all__ = [
    "MCAP_MAGIC",
    "BagLocation",
    "FileBytes",
    "is_file_compressed",
    "locate",
    "mapped_file",
    "other_storage",
]

MCAP_MAGIC = b"\x89MCAP0\r\n"
_SQLITE_MAGIC = b"SQLite format 3\x00"
_ROS1_MAGIC = b"#ROSBAG V"
_ZSTD_MAGIC = b"\x28\xb5\x2f\xfd"


@dataclass(frozen=True)
class BagLocation:
    """A bag on disk: the folder, its ``metadata.yaml`` (None for a bare file) and its storage files."""

    directory: Path
    metadata: BagMetadata | None
    files: tuple[Path, ...]

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
    return OtherStorageError(f"{path}: {kind} storage, not MCAP (smm-bag reads only MCAP bags)")


def locate(path: Path) -> BagLocation:
    """The bag at ``path``: a rosbag2 folder or one bare ``.mcap`` / ``.mcap.zstd`` file.

    Raises:
        OtherStorageError: The bag uses another storage (sqlite3 ``.db3``, ROS 1 ``.bag``).
        NotABagError: Neither a rosbag2 folder nor an MCAP file.
        CorruptBagError: ``metadata.yaml`` is unreadable.
    """
    if path.is_file():
        kind = other_storage(path)
        if kind is not None:
            raise _other_storage_error(path, kind)
        if path.name == METADATA_FILE:
            return locate(path.parent)
        with path.open("rb") as stream:
            head = stream.read(len(MCAP_MAGIC))
        if head != MCAP_MAGIC and not head.startswith(_ZSTD_MAGIC):
            raise NotABagError(f"{path} is not a directory (a rosbag2 bag folder) nor an MCAP file")
        return BagLocation(path.parent, None, (path,))
    if not path.is_dir():
        raise NotABagError(
            f"{path} is not a directory (a rosbag2 bag is a folder with metadata.yaml) nor a file"
        )
    if not (path / METADATA_FILE).is_file():
        for candidate in sorted(path.iterdir()):
            kind = other_storage(candidate) if candidate.is_file() else None
            if kind is not None:
                raise _other_storage_error(path, kind)
    metadata = read_metadata(path)
    if metadata.storage_identifier != "mcap":
        raise _other_storage_error(path, metadata.storage_identifier or "unnamed")
    if not metadata.files:
        raise NotABagError(f"{path}: metadata.yaml lists no storage file")
    return BagLocation(path, metadata, tuple(path / info.path for info in metadata.files))


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
def mapped_file(path: Path) -> Iterator[FileBytes]:
    """The MCAP bytes of a storage file, decompressed to a temporary file first if file-compressed."""
    if not is_file_compressed(path):
        with _mapped(path) as data:
            yield FileBytes(data, True)
        return
    handle, name = tempfile.mkstemp(prefix="smm-bag-", suffix=".mcap")
    os.close(handle)
    temporary = Path(name)
    try:
        complete = _decompress(path, temporary)
        with _mapped(temporary) as data:
            yield FileBytes(data, complete)
    finally:
        temporary.unlink(missing_ok=True)
