"""The corpus: each entry is a writer with its options, how to build it, and its expected outcome per command.

Expected outcomes are (exit code, class); classes: ``ok`` (info: its counts equal the files' messages),
``intact`` (repair: said intact, every file byte for byte unchanged), ``same metrics`` (analyze:
metrics.json equal to the original's), ``reproduces`` (rerun --expect-equal), ``repaired`` (every message a
sequential read gives is kept), ``not the stack's topics`` (analyze: one error line), ``truncated``,
``corrupt``; ``-`` where a command does not apply.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from bag.corpus import writers as w
from rosbags.rosbag2.enums import StoragePlugin

COMMANDS = ("info", "repair", "analyze", "rerun")
Outcome = tuple[int, str]

OK: Outcome = (0, "ok")
INTACT: Outcome = (0, "intact")
SAME: Outcome = (0, "same metrics")
REPRODUCES: Outcome = (0, "reproduces")
NOT_OURS: Outcome = (6, "not the stack's topics")
OTHER_STORAGE: Outcome = (9, "other storage")
SKIP: Outcome = (-1, "-")
SHOWN: Outcome = (-2, "shown")
"""Shown in the table, not checked (info on a framing-damaged copy: an error, or the counts indexes give)."""


@dataclass(frozen=True)
class Entry:
    """One bag of the corpus."""

    name: str
    writer: str
    options: str
    build: Callable[[Path], Path]
    expect: dict[str, Outcome]
    fast: bool = False
    damage: str = ""
    """For damaged copies: what was damaged (repair must keep what the sequential read gives)."""
    padded_chunks: bool = False
    """mcap-python's StreamReader misreads padded records inside chunks: the byte reader counts instead."""
    tags: frozenset[str] = field(default_factory=frozenset)


def valid(manifest: bool = True) -> dict[str, Outcome]:
    return {"info": OK, "repair": INTACT, "analyze": SAME, "rerun": REPRODUCES if manifest else SKIP}


def _file(name: str, make: Callable[[Path], Path]) -> Callable[[Path], Path]:
    return lambda root: make(root / f"{name}.mcap")


def _rosbags() -> list[Entry]:
    entries = []
    for version in (4, 5, 6, 7, 8, 9):
        name = f"rosbags-v{version}"
        entries.append(
            Entry(
                name,
                "rosbags 0.11.9",
                f"metadata version {version}, zstd chunks without CRC",
                lambda root, v=version, n=name: w.rosbags_bag(root / n, version=v, compression="storage"),
                valid(manifest=version >= 6),
                fast=version in (4, 9),
            )
        )
    for mode, fast in (("none", False), ("file", True), ("message", False)):
        name = f"rosbags-{mode}"
        entries.append(
            Entry(
                name,
                "rosbags 0.11.9",
                {
                    "none": "uncompressed chunks",
                    "file": "file compression (.mcap.zstd)",
                    "message": "message compression (zstd)",
                }[mode],
                lambda root, m=mode, n=name: w.rosbags_bag(root / n, compression=m),
                valid(),
                fast=fast,
            )
        )
    entries.append(
        Entry(
            "rosbags-sqlite3",
            "rosbags 0.11.9",
            "sqlite3 storage (.db3)",
            lambda root: w.rosbags_bag(root / "rosbags-sqlite3", storage=StoragePlugin.SQLITE3),
            {"info": OK, "repair": OTHER_STORAGE, "analyze": SAME, "rerun": REPRODUCES},
            fast=True,
        )
    )
    entries.append(
        Entry(
            "rosbags-3files",
            "rosbags 0.11.9",
            "3 files",
            lambda root: w.rosbags_bag(root / "rosbags-3files", compression="storage", files=3),
            valid(),
            fast=True,
        )
    )
    return entries


def _mcap() -> list[Entry]:
    variants: list[tuple[str, str, w.McapOptions, bool]] = [
        ("mcap-default", "chunked 1 MiB, zstd, CRCs, summary", w.McapOptions(), False),
        ("mcap-unchunked", "unchunked", w.McapOptions(chunked=False), True),
        (
            "mcap-unchunked-nosummary",
            "unchunked, no summary",
            w.McapOptions(chunked=False, summary=False),
            False,
        ),
        ("mcap-none", "uncompressed chunks", w.McapOptions(compression="none"), False),
        ("mcap-lz4", "lz4 chunks", w.McapOptions(compression="lz4"), True),
        ("mcap-chunk4k", "4 KiB chunks", w.McapOptions(chunk_size=4096), False),
        (
            "mcap-chunk64k-none",
            "64 KiB uncompressed chunks",
            w.McapOptions(chunk_size=65536, compression="none"),
            False,
        ),
        ("mcap-nocrc", "CRCs off", w.McapOptions(crcs=False), True),
        ("mcap-datacrc", "data-section CRC on", w.McapOptions(data_crc=True), False),
        (
            "mcap-nosummary",
            "no summary (no indexes, statistics, offsets)",
            w.McapOptions(summary=False),
            False,
        ),
        ("mcap-noindex", "no chunk or message index", w.McapOptions(indexes=False), False),
        ("mcap-norepeat", "no schemas or channels in the summary", w.McapOptions(repeat=False), False),
        ("mcap-nostatistics", "no statistics", w.McapOptions(statistics=False), False),
        ("mcap-nooffsets", "no summary offsets", w.McapOptions(offsets=False), False),
        (
            "mcap-nocrc-nosummary-lz4",
            "lz4, CRCs off, no summary",
            w.McapOptions(compression="lz4", crcs=False, summary=False),
            False,
        ),
        ("mcap-manifest", "manifest in the rosbag2 metadata record", w.McapOptions(manifest=True), True),
        (
            "mcap-manifest-unchunked-nocrc",
            "manifest; unchunked, CRCs off",
            w.McapOptions(manifest=True, chunked=False, crcs=False),
            False,
        ),
    ]
    entries = [
        Entry(
            name,
            "mcap 1.6.0 (Python)",
            f"bare .mcap file: {text}",
            _file(name, lambda p, o=o: w.mcap_file(p, o)),
            valid(o.manifest),
            fast=fast,
        )
        for name, text, o, fast in variants
    ]
    entries.append(
        Entry(
            "mcap-folder-v9",
            "mcap 1.6.0 (Python)",
            "folder with metadata.yaml v9, lz4 chunks",
            lambda root: w.in_folder(
                w.mcap_file(root / "mcap-folder-v9.mcap", w.McapOptions(compression="lz4"))
            ),
            valid(),
        )
    )
    entries.append(
        Entry(
            "mcap-service-events",
            "mcap 1.6.0 (Python)",
            "bare .mcap file: a service's event topic",
            _file(
                "mcap-service-events", lambda p: w.mcap_file(p, w.McapOptions(extra_topic=w.SERVICE_EVENTS))
            ),
            valid(manifest=False),
        )
    )
    entries.append(
        Entry(
            "mcap-not-installed",
            "mcap 1.6.0 (Python)",
            "an extra topic of a type not installed",
            _file(
                "mcap-not-installed",
                lambda p: w.mcap_file(p, w.McapOptions(manifest=True, extra_topic=w.NOT_INSTALLED)),
            ),
            valid(),
            fast=True,
            tags=frozenset({"not installed"}),
        )
    )
    return entries


def _js() -> list[Entry]:
    variants: list[tuple[str, str, dict[str, object], bool]] = [
        ("js-default", "chunked, uncompressed, every index", {}, True),
        ("js-zstd", "zstd chunks", {"compression": "zstd"}, False),
        ("js-lz4-64k", "lz4, 64 KiB chunks", {"compression": "lz4", "chunkSize": 65536}, True),
        ("js-unchunked", "unchunked", {"useChunks": False}, False),
        (
            "js-bare",
            "no statistics, summary offsets, indexes, repeated schemas/channels",
            {
                "useStatistics": False,
                "useSummaryOffsets": False,
                "useChunkIndex": False,
                "useMessageIndex": False,
                "repeatSchemas": False,
                "repeatChannels": False,
                "useMetadataIndex": False,
            },
            False,
        ),
    ]
    return [
        Entry(
            name,
            "@mcap/core 2.2.2 (node)",
            f"bare .mcap file: {text}",
            _file(name, lambda p, o=o: w.js_file(p, o)),
            valid(),
            fast=fast,
        )
        for name, text, o, fast in variants
    ]


_FAST_SHAPES = {
    frozenset(),
    frozenset({"ch", "crc0"}),
    frozenset({"ch", "mx", "chx", "st", "sum", "rch", "rsh", "pad"}),
}


def _shapes() -> list[Entry]:
    entries = [
        Entry(
            w.shape_name(features),
            "conformance shapes (own generator)",
            " ".join(sorted(features)) or "unchunked, no summary",
            _file(w.shape_name(features), lambda p, f=features: w.shape_file(p, f)),
            valid(manifest=False),
            fast=features in _FAST_SHAPES,
            padded_chunks="inner-pad" in features,
        )
        for features in w.shapes()
    ]
    inner = frozenset({"ch", "mx", "chx", "st", "sum", "rch", "rsh", "inner-pad"})
    entries.append(
        Entry(
            w.shape_name(inner),
            "own generator (beyond the suite)",
            "records inside chunks padded too (the spec's rule: readers skip a record's extra bytes)",
            _file(w.shape_name(inner), lambda p: w.shape_file(p, inner)),
            valid(manifest=False),
            padded_chunks=True,
        )
    )
    schemaless = frozenset({"ch", "mx", "chx", "st", "sum", "rch", "rsh", "schemaless"})
    entries.append(
        Entry(
            w.shape_name(schemaless),
            "own generator (beyond the suite)",
            "an extra channel without schema (schema id 0, JSON), as the conformance suite's "
            "OneSchemalessMessage",
            _file(w.shape_name(schemaless), lambda p: w.shape_file(p, schemaless)),
            valid(manifest=False),
        )
    )
    other = frozenset({"ch", "mx", "chx", "st", "rch", "rsh"})
    entries.append(
        Entry(
            "shape-other-topics",
            "conformance shapes (own generator)",
            "topics that are not the stack's",
            _file("shape-other-topics", lambda p: w.shape_file(p, other, topics_of="other")),
            {"info": OK, "repair": INTACT, "analyze": NOT_OURS, "rerun": SKIP},
            fast=True,
        )
    )
    return entries


# --------------------------------------------------------------------------------------------- damaged


def _damaged(base: Entry, kind: str, fast: bool) -> Entry:
    expect = {
        "info": (4, "truncated") if kind.startswith("cut") else SHOWN,
        "repair": (0, "repaired"),
        "analyze": SKIP,
        "rerun": SKIP,
    }

    def build(root: Path) -> Path:
        bag = base.build(root)
        return bag if bag.is_dir() else w.in_folder(bag)  # repair is tried on a bag folder

    return Entry(
        f"{base.name}+{kind}",
        base.writer,
        f"{base.options.replace('bare .mcap file: ', '')} (in a folder); {DAMAGES[kind]}",
        build,
        expect,
        fast=fast,
        damage=kind,
        padded_chunks=base.padded_chunks,
    )


DAMAGES = {
    "cut-mid": "cut at 45 % of the data section",
    "cut-summary": "cut in the summary",
    "length": "the length of a record in mid-file overwritten (framing)",
    "opcode": "the opcode of a record in mid-file zeroed (framing)",
}


def entries() -> list[Entry]:
    """Every entry of the corpus (``make test-bags``); ``fast`` ones run in ``make test``."""
    every = _rosbags() + _mcap() + _js() + _shapes()
    by_name = {entry.name: entry for entry in every}
    damaged = []
    for name, fast in (
        ("mcap-unchunked", True),
        ("mcap-nocrc", False),
        ("js-default", False),
        ("shape-ch-crc0", True),
        ("shape-plain", False),
        ("mcap-chunk64k-none", False),
        ("mcap-lz4", False),
        ("rosbags-none", False),
    ):
        damaged += [_damaged(by_name[name], kind, fast and kind in ("cut-mid", "length")) for kind in DAMAGES]
    return every + damaged


def selected() -> list[Entry]:
    """The entries this session runs: every one when ``SMM_BAG_CORPUS=full``, else the fast ones."""
    full = os.environ.get("SMM_BAG_CORPUS", "") == "full"
    return [entry for entry in entries() if full or entry.fast]
