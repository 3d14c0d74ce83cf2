"""Text of an ``smm-bag repair`` report: per file what checked, what was lost and where the original is."""

from __future__ import annotations

from collections.abc import Mapping

from smm_bag.repair import FileRepair, RepairReport

__all__ = ["format_repair"]


def _time(ns: int | None, open_end: str) -> str:
    return open_end if ns is None else f"{ns // 1_000_000_000}.{ns % 1_000_000_000:09d} s"


def _per_topic(counts: Mapping[str, int]) -> str:
    return ", ".join(f"{topic} {count}" for topic, count in sorted(counts.items()))


def _file_lines(item: FileRepair) -> list[str]:
    if item.status == "intact":
        return [f"{item.path}: intact ({item.messages} messages in {item.chunks} chunks; {item.checked})"]
    if item.status in ("missing", "unsalvageable"):
        return [f"{item.path}: {item.status}: {item.reason or 'nothing checks'}; left as it was"]
    lines = [
        f"{item.path}: damaged: {item.reason}",
        f"  kept {item.messages} messages in {item.chunks} chunks",
    ]
    chunks = (
        f"{item.lost_chunks} chunks"
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
