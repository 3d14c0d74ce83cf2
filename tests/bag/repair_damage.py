"""Damaged copies of real bags and the checks of ``smm-bag repair`` on them (tests and bench_repair.py).

The oracle reads the original and repaired files with the ``mcap`` library and rosbags only, never with
``smm_bag``'s scanner: what a repaired bag holds is compared message by message with the original.
"""

from __future__ import annotations

import io
import random
import shutil
import struct
import zlib
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import yaml
from bag.bag_helpers import T0, TOPICS
from mcap.data_stream import ReadDataStream
from mcap.reader import make_reader
from mcap.records import Channel, Chunk, Message, Schema
from mcap.stream_reader import StreamReader, breakup_chunk
from rosbags.highlevel import AnyReader
from smm_bag.commands import repair as repair_command
from smm_bag.exit_codes import EXIT_OK, EXIT_UNSALVAGEABLE
from smm_bag.writer import BagWriter, WriterOptions

SAMPLE = Path(__file__).resolve().parents[2] / "bags" / "sample_case2_fpdeso"
KINDS = ("truncation", "chunk bit flip", "zeroed 4 KiB block", "summary or footer", "metadata.yaml")
BLOCK = 4096

MessageKey = tuple[str, int, int, bytes]


@dataclass(frozen=True)
class Place:
    """One damaged place: its kind, which storage file, where in the kind's region (0..1), which bit."""

    kind: str
    file: int
    where: float
    bit: int


def random_places(rng: random.Random, most: int = 3) -> list[Place]:
    """One to ``most`` damaged places of random kinds."""
    return [
        Place(rng.choice(KINDS), rng.randrange(8), rng.random(), rng.randrange(8))
        for _ in range(rng.randint(1, most))
    ]


def write_source_bag(path: Path) -> Path:
    """A bag of every recorded type, zstd chunks finished every 20 messages, split into several files."""
    now = [0]
    options = WriterOptions(compression="zstd", flush_interval_ns=20, max_size_bytes=64 * 1024)
    with BagWriter(path, options, clock=lambda: now[0]) as writer:
        for topic, (type_name, _) in TOPICS.items():
            writer.create_topic(topic, type_name)
        for k in range(2400):
            topic = list(TOPICS)[k % len(TOPICS)]
            now[0] += 1
            writer.write(topic, TOPICS[topic][1](k), T0 + k * 1_000_000)
    return path


@dataclass
class OriginalFile:
    """One intact storage file: its chunks (offset, length, messages) and the summary's start."""

    name: str
    size: int
    summary_start: int
    chunks: list[tuple[int, int, list[MessageKey]]]
    definitions: dict[int, list[tuple[int, int]]]  # channel id -> chunk (offset, length) holding its records
    schema_of: dict[int, int]  # channel id -> schema id
    schema_chunks: dict[int, list[tuple[int, int]]]


def read_original(bag: Path) -> list[OriginalFile]:
    """The chunks and messages of every storage file of an intact bag, through the mcap library."""
    files = []
    for path in sorted(bag.glob("*.mcap"), key=lambda p: int(p.stem.rsplit("_", 1)[1])):
        data = path.read_bytes()
        reader = make_reader(io.BytesIO(data))
        summary = reader.get_summary()
        assert summary is not None
        topics = {cid: channel.topic for cid, channel in summary.channels.items()}
        original = OriginalFile(path.name, len(data), 0, [], {}, {}, {})
        original.summary_start = struct.unpack_from("<Q", data, len(data) - 8 - 20)[0]
        for index in summary.chunk_indexes:
            start, length = index.chunk_start_offset, index.chunk_length
            chunk = Chunk.read(ReadDataStream(io.BytesIO(data[start + 9 : start + length])))
            messages = []
            for record in breakup_chunk(chunk, validate_crc=True):
                if isinstance(record, Message):
                    messages.append(
                        (topics[record.channel_id], record.log_time, record.publish_time, record.data)
                    )
                elif isinstance(record, Channel):
                    original.definitions.setdefault(record.id, []).append((start, length))
                    original.schema_of[record.id] = record.schema_id
                elif isinstance(record, Schema):
                    original.schema_chunks.setdefault(record.id, []).append((start, length))
            original.chunks.append((start, length, messages))
        files.append(original)
    return files


@dataclass(frozen=True)
class Damaged:
    """A damaged copy: where it is, and whether its metadata.yaml now says something else."""

    bag: Path
    metadata_damaged: bool


def damage_copy(
    source: Path, originals: Sequence[OriginalFile], target: Path, places: Sequence[Place]
) -> Damaged:
    """Copies ``source`` to ``target`` and damages it at ``places``; returns what changed."""
    shutil.copytree(source, target)
    metadata_text = (target / "metadata.yaml").read_bytes()
    contents = {o.name: bytearray((target / o.name).read_bytes()) for o in originals}
    for place in places:
        if place.kind == "metadata.yaml":
            path = target / "metadata.yaml"
            text = bytearray(path.read_bytes())
            at = int(place.where * len(text))
            if place.bit % 2:
                text = text[:at]
            else:
                text[at : at + 3] = b"\x99: ["
            path.write_bytes(bytes(text))
            continue
        original = originals[place.file % len(originals)]
        data = contents[original.name]
        if place.kind == "truncation":
            del data[8 + int(place.where * (len(data) - 8)) :]
        elif place.kind == "chunk bit flip":
            start, length, _ = original.chunks[int(place.where * len(original.chunks))]
            at = start + int((place.where * len(original.chunks)) % 1 * length)
            if at < len(data):
                data[at] ^= 1 << place.bit
        elif place.kind == "zeroed 4 KiB block":
            at = int(place.where * len(data)) // BLOCK * BLOCK
            data[at : at + BLOCK] = bytes(len(data[at : at + BLOCK]))
        else:
            start = original.summary_start
            at = start + int(place.where * (original.size - start))
            if at < len(data):
                data[at] ^= 1 << place.bit
    for name, data in contents.items():
        (target / name).write_bytes(bytes(data))
    try:
        now = yaml.safe_load((target / "metadata.yaml").read_bytes())
        changed = now != yaml.safe_load(metadata_text)
    except (yaml.YAMLError, UnicodeDecodeError):
        changed = True
    return Damaged(target, changed)


def _touched(ranges: Sequence[tuple[int, int]], start: int, length: int) -> bool:
    return any(low < start + length and start < high for low, high in ranges)


def _exact_changes(original: bytes, damaged: bytes) -> list[tuple[int, int]]:
    """Changed byte ranges, exact to the byte (the block-wise ranges narrowed)."""
    ranges = []
    for position in range(0, min(len(original), len(damaged)), BLOCK):
        a, b = original[position : position + BLOCK], damaged[position : position + BLOCK]
        if a != b:
            differ = [i for i in range(min(len(a), len(b))) if a[i] != b[i]] or [len(b)]
            first, last = differ[0], differ[-1]
            ranges.append((position + first, position + last + 1))
    if len(damaged) < len(original):
        ranges.append((len(damaged), len(original)))
    return ranges


def file_checks(data: bytes) -> bool:
    """Every CRC of an MCAP file checks, read by the mcap library and the spec's summary-CRC rule."""
    try:
        for _ in StreamReader(io.BytesIO(data), validate_crcs=True).records:
            pass
        footer_at = len(data) - 8 - 29
        summary_start, offset_start, crc = struct.unpack_from("<QQI", data, footer_at + 9)
    except Exception:
        return False
    return crc != 0 and zlib.crc32(data[summary_start : footer_at + 25]) == crc and offset_start >= 0


def _mcap_messages(path: Path) -> list[MessageKey]:
    reader = make_reader(path.open("rb"), validate_crcs=True)
    return [
        (c.topic, m.log_time, m.publish_time, m.data)
        for _, c, m in reader.iter_messages(log_time_order=False)
    ]


@dataclass
class Outcome:
    """What one repair kept of one damaged copy (message counts)."""

    exit_code: int
    original: int
    kept: int
    undamaged: int
    intact_files: int
    repaired_files: int
    unsalvageable_files: int


def repair_and_check(source: Path, originals: Sequence[OriginalFile], damaged: Damaged) -> Outcome:
    """Runs ``smm-bag repair`` on a damaged copy and checks the result against the original (asserts)."""
    bag = damaged.bag
    sources = {o.name: (source / o.name).read_bytes() for o in originals}
    before = {o.name: (bag / o.name).read_bytes() for o in originals}
    out, err = io.StringIO(), io.StringIO()
    code = repair_command(bag, stdout=out, stderr=err)  # an exception here is the traceback a user would see
    text = out.getvalue()
    assert "Traceback" not in text + err.getvalue()
    if code == EXIT_UNSALVAGEABLE and not text:  # no file holds anything that checks: the bag is left alone
        assert {o.name: (bag / o.name).read_bytes() for o in originals} == before
        total = sum(len(ms) for o in originals for _, _, ms in o.chunks)
        return Outcome(code, total, 0, 0, 0, 0, len(originals))
    status = {}
    for o in originals:
        line = next((ln for ln in text.splitlines() if ln.startswith(f"{o.name}: ")), "")
        status[o.name] = line[len(o.name) + 2 :].split(":")[0].split(" (")[0]
    assert code in (EXIT_OK, EXIT_UNSALVAGEABLE), (code, text, err.getvalue())
    assert (code == EXIT_UNSALVAGEABLE) == any(s == "unsalvageable" for s in status.values()), text
    outcome = Outcome(code, 0, 0, 0, 0, 0, 0)
    listed = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    listed_files = {entry["path"]: entry for entry in listed["files"]}
    kept_per_topic: Counter[str] = Counter()
    for o in originals:
        damaged_bytes = before[o.name]
        after = (bag / o.name).read_bytes()
        changes = _exact_changes(sources[o.name], damaged_bytes)
        everything = [m for _, _, ms in o.chunks for m in ms]
        outcome.original += len(everything)
        if status[o.name] == "intact":
            outcome.intact_files += 1
            assert after == damaged_bytes, f"{o.name}: an intact file was changed"
            assert file_checks(after), f"{o.name}: called intact, but a CRC does not check:\n{text}"
            assert _mcap_messages(bag / o.name) == everything, f"{o.name}: called intact, messages differ"
        if not changes:
            assert status[o.name] == "intact", (
                f"{o.name}: undamaged, but repair said {status[o.name]!r}:\n{text}"
            )
        if status[o.name] == "unsalvageable":
            outcome.unsalvageable_files += 1
            assert after == damaged_bytes, f"{o.name}: nothing saved, yet the file was changed"
            assert o.name not in listed_files
            continue
        assert o.name in listed_files, f"{o.name} missing from the rebuilt metadata.yaml"
        if status[o.name] == "damaged":
            outcome.repaired_files += 1
            assert (bag / f"{o.name}.damaged").read_bytes() == damaged_bytes, "original not kept as .damaged"
        kept = _mcap_messages(bag / o.name)
        assert not Counter(kept) - Counter(everything), f"{o.name}: a kept message is not in the original"
        position = {message: i for i, message in enumerate(everything)}
        order = [position[message] for message in kept]
        assert order == sorted(order), f"{o.name}: kept messages out of their original order"
        # A channel is usable if its record and its schema's record survive in an undamaged copy.
        summary_ok = not _touched(changes, o.summary_start, o.size - o.summary_start)

        def survives(copies: list[tuple[int, int]]) -> bool:
            return summary_ok or any(not _touched(changes, s, n) for s, n in copies)  # noqa: B023

        usable_topics = set()
        reader = make_reader(io.BytesIO(sources[o.name]))
        summary = reader.get_summary()
        assert summary is not None
        for cid, channel in summary.channels.items():
            schema_ok = channel.schema_id == 0 or survives(o.schema_chunks.get(channel.schema_id, []))
            if survives(o.definitions.get(cid, [])) and schema_ok:
                usable_topics.add(channel.topic)
        must = [
            m
            for start, length, messages in o.chunks
            if not _touched(changes, start, length)
            for m in messages
            if m[0] in usable_topics
        ]
        assert not Counter(must) - Counter(kept), (
            f"{o.name}: a message of an undamaged chunk was lost:\n{text}"
        )
        outcome.undamaged += len(must)
        outcome.kept += len(kept)
        kept_per_topic.update(m[0] for m in kept)
        entry = listed_files[o.name]
        assert entry["message_count"] == len(kept)
        if kept:
            times = [m[1] for m in kept]
            assert entry["starting_time"]["nanoseconds_since_epoch"] == min(times)
            assert entry["duration"]["nanoseconds"] == max(times) - min(times)
    counts = {t["topic_metadata"]["name"]: t["message_count"] for t in listed["topics_with_message_count"]}
    assert {k: v for k, v in counts.items() if v} == dict(kept_per_topic), (
        "metadata.yaml differs from the files"
    )
    assert listed["message_count"] == outcome.kept
    if outcome.kept or code == EXIT_OK:
        with AnyReader([bag]) as reader:
            raw = Counter((c.topic, t, bytes(d)) for c, t, d in reader.messages())
        assert sum(raw.values()) == outcome.kept, "rosbags reads another number of messages"
    if damaged.metadata_damaged:
        assert (bag / "metadata.yaml.damaged").exists()
    return outcome
