"""Typed errors of the bag library (each a ``ValueError``; the CLI maps each class to an exit code)."""

__all__ = [
    "BagError",
    "BagExistsError",
    "CorruptBagError",
    "MissingTopicsError",
    "NotABagError",
    "OtherStorageError",
    "TruncatedBagError",
    "UnknownTypeError",
    "UnsalvageableFileError",
    "WriterStateError",
]


class BagError(ValueError):
    """Base class of every error raised by ``smm_bag``."""


class NotABagError(BagError):
    """The path is not a rosbag2 directory: missing or unreadable ``metadata.yaml``, or no storage file."""


class OtherStorageError(BagError):
    """The bag uses a storage other than MCAP (sqlite3 ``.db3``, ROS 1 ``.bag``): the message names it."""


class TruncatedBagError(BagError):
    """A storage file ends early (recording killed before it closed the file): ``smm-bag repair`` fixes it."""


class CorruptBagError(BagError):
    """A storage file or ``metadata.yaml`` is damaged or disagrees with the other (bad magic, CRC, counts)."""


class MissingTopicsError(BagError):
    """The bag lacks a topic the operation needs (the message names them)."""


class BagExistsError(BagError):
    """The output directory of a new bag already exists (rosbag2 never overwrites a bag)."""


class UnknownTypeError(BagError):
    """No message definition is known for a message type."""


class WriterStateError(BagError):
    """A writer call out of order: write before create_topic, write after close, duplicate topic."""


class UnsalvageableFileError(BagError):
    """No record of a storage file checks: ``smm-bag repair`` saves nothing of it and leaves it as it was."""
