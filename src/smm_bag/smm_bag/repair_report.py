"""The report of ``smm-bag repair``: per file what checked, what was lost, where the original is; its text."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from smm_bag.errors import BagError
from smm_bag.metadata import BagMetadata

__all__ = ["FileRepair", "RepairReport", "format_repair"]


@dataclass(frozen=True)
class FileRepair:
    """What repair found in one storage file and did to it.

    Attributes:
        path: File name inside the bag.
        status: ``intact`` (left untouched), ``repaired`` (rewritten), ``unsalvageable`` (nothing in it
            checks; left as it was) or ``missing`` (listed in ``metadata.yaml``, not on disk).
        messages: Messages in the file after repair.
        chunks: Chunks whose CRC checks (kept).
        lost_chunks: Chunks lost: exact with a chunk index that checks, else the damaged chunk records found.
        lost_chunks_exact: True if ``lost_chunks`` comes from a chunk index that checks.
        lost_messages: Messages lost per topic, where the file's statistics say (empty if unknown).
        lost_ranges: Log-time ranges (ns) of lost data: exact from the chunk index, else the gap between
            the kept chunks around a damaged place (None: open end).
        findings: Every damaged place and disagreement found (empty if intact).
        backup: Name of the kept original, if any.
        error: Why nothing could be saved (status ``unsalvageable``).
        checked: For an intact file, which CRCs it holds and that they check.
    """

    path: str
    status: str
    messages: int = 0
    chunks: int = 0
    lost_chunks: int = 0
    lost_chunks_exact: bool = True
    lost_messages: Mapping[str, int] = field(default_factory=dict)
    lost_ranges: tuple[tuple[int | None, int | None], ...] = ()
    findings: tuple[str, ...] = ()
    backup: str = ""
    error: BagError | None = None
    checked: str = ""

    @property
    def rebuilt(self) -> bool:
        """True if the file was rewritten."""
        return self.status == "repaired"

    @property
    def reason(self) -> str:
        """The findings in one line."""
        return "; ".join(self.findings)


@dataclass(frozen=True)
class RepairReport:
    """Result of :func:`repair_bag`: per-file results, the new metadata and what became of the old one.

    Attributes:
        files: Per storage file.
        metadata: The metadata now in ``metadata.yaml``.
        metadata_note: What was wrong with the old ``metadata.yaml`` (empty if it agreed with the files
            before repair).
        metadata_rewritten: True if ``metadata.yaml`` was written.
        metadata_backup: Name of the kept old ``metadata.yaml``, if any.
        lost_messages: Messages per topic the old ``metadata.yaml`` listed and the files no longer hold.
        bare: One storage file was repaired, not a bag folder (no ``metadata.yaml`` is read or written).
    """

    files: tuple[FileRepair, ...]
    metadata: BagMetadata
    metadata_note: str = ""
    metadata_rewritten: bool = False
    metadata_backup: str = ""
    lost_messages: Mapping[str, int] = field(default_factory=dict)
    bare: bool = False

    @property
    def changed(self) -> bool:
        """True if any file was rebuilt."""
        return any(item.rebuilt for item in self.files)

    @property
    def errors(self) -> tuple[BagError, ...]:
        """The errors of files nothing could be saved from."""
        return tuple(item.error for item in self.files if item.error is not None)


def _time(ns: int | None, open_end: str) -> str:
    return open_end if ns is None else f"{ns // 1_000_000_000}.{ns % 1_000_000_000:09d} s"


def _per_topic(counts: Mapping[str, int]) -> str:
    return ", ".join(f"{topic} {count}" for topic, count in sorted(counts.items()))


def _file_lines(item: FileRepair) -> list[str]:
    if item.status == "intact":
        return [f"{item.path}: intact ({item.messages} messages in {item.chunks} chunks; {item.checked})"]
    if item.status in ("missing", "unsalvageable"):
        return [f"{item.path}: {item.status}: {item.reason or 'nothing checks'}; left as it was"]
    unchunked = not item.chunks and not item.lost_chunks
    lines = [
        f"{item.path}: damaged: {item.reason}",
        f"  kept {item.messages} messages " + ("(no chunks)" if unchunked else f"in {item.chunks} chunks"),
    ]
    chunks = (
        "no chunk"
        if unchunked
        else f"{item.lost_chunks} chunks"
        if item.lost_chunks_exact
        else (f"at least {item.lost_chunks} chunks (no chunk index that checks)")
    )
    messages = (
        f"{sum(item.lost_messages.values())} messages ({_per_topic(item.lost_messages)})"
        if item.lost_messages
        else "messages per topic unknown (no statistics that check)"
        if not item.lost_chunks_exact
        else "no message"
    )
    lines.append(f"  lost {chunks}, {messages}")
    for start, end in item.lost_ranges:
        lines.append(f"  lost log time from {_time(start, 'the start')} to {_time(end, 'the end')}")
    if item.backup:
        lines.append(f"  original kept as {item.backup}")
    return lines


def format_repair(report: RepairReport) -> str:
    """The report as printed by ``smm-bag repair``."""
    lines = [line for item in report.files for line in _file_lines(item)]
    if report.bare:
        return "\n".join([*lines, "metadata.yaml: none (a storage file given alone; nothing written)"])
    metadata = report.metadata
    summary = (
        f"{metadata.message_count} messages on {len(metadata.topics)} topics in {len(metadata.files)} file(s)"
    )
    if report.metadata_rewritten:
        summary = f"rebuilt to what the files hold: {summary}"
    if report.metadata_note:
        summary = f"{report.metadata_note}; {summary}"
    if report.metadata_backup:
        summary += f"; original kept as {report.metadata_backup}"
    lines.append(f"metadata.yaml: {summary}")
    if report.lost_messages:
        lines.append(f"  lost against the old metadata.yaml: {_per_topic(report.lost_messages)}")
    return "\n".join(lines)
