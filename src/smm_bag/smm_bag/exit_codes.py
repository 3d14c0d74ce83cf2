"""Exit codes of ``smm-bag`` and the code of each library error (shared by every layer's subcommands)."""

from __future__ import annotations

from typing import TextIO

from smm_bag.errors import (
    BagError,
    CorruptBagError,
    MissingTopicsError,
    NotABagError,
    OtherStorageError,
    TruncatedBagError,
    UnsalvageableFileError,
)

__all__ = [
    "EXIT_CHECK_FAILED",
    "EXIT_CORRUPT",
    "EXIT_MISSING_TOPICS",
    "EXIT_NOT_A_BAG",
    "EXIT_OK",
    "EXIT_OTHER_STORAGE",
    "EXIT_PARAMS",
    "EXIT_TRUNCATED",
    "EXIT_UNSALVAGEABLE",
    "EXIT_USAGE",
    "exit_code",
    "fail",
]

EXIT_OK = 0
EXIT_CHECK_FAILED = 1
EXIT_USAGE = 2
EXIT_NOT_A_BAG = 3
EXIT_TRUNCATED = 4
EXIT_CORRUPT = 5
EXIT_MISSING_TOPICS = 6
EXIT_PARAMS = 7
"""A parameters file of ``smm-bag rerun`` is unreadable or invalid (``smm_analysis.errors``)."""
EXIT_UNSALVAGEABLE = 8
"""``smm-bag repair`` could save nothing of a storage file (the file is left as it was)."""
EXIT_OTHER_STORAGE = 9
"""The bag uses a storage other than MCAP (sqlite3 ``.db3``, ROS 1 ``.bag``); nothing was read."""


def exit_code(error: BagError) -> int:
    """The exit code of a library error."""
    for kind, code in (
        (OtherStorageError, EXIT_OTHER_STORAGE),
        (NotABagError, EXIT_NOT_A_BAG),
        (TruncatedBagError, EXIT_TRUNCATED),
        (CorruptBagError, EXIT_CORRUPT),
        (MissingTopicsError, EXIT_MISSING_TOPICS),
        (UnsalvageableFileError, EXIT_UNSALVAGEABLE),
    ):
        if isinstance(error, kind):
            return code
    return EXIT_USAGE


def fail(error: BagError, stderr: TextIO) -> int:
    """Print ``error`` as ``smm-bag: error: ...`` and return its exit code."""
    stderr.write(f"smm-bag: error: {error}\n")
    return exit_code(error)
