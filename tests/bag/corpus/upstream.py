"""Bags of an external directory (rosbag2's test bags, the MCAP conformance files): never committed here.

``make test-bags UPSTREAM=DIR`` runs the corpus checks over every bag folder (one with metadata.yaml) and
every bare ``.mcap`` or ``.db3`` file outside such folders under DIR. A sqlite3 bag is also converted
(``smm-bag convert``): the MCAP bag must hold the same messages by mcap's reader and by rosbags', and
``info`` must count them so.
"""

from __future__ import annotations

import shutil
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import yaml

if __package__ in (None, ""):
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from bag.corpus.run import (
    Result,
    file_bytes,
    hashes,
    info_counts,
    smm_bag,
    sqlite_messages,
    storage_files,
    topic_messages,
)
from bag.corpus.sample import Key, file_messages


def bags(directory: str) -> list[Path]:
    """Bag folders and bare MCAP files under ``directory`` ("" or missing: none)."""
    if not directory or not Path(directory).is_dir():
        return []
    root = Path(directory)
    folders = sorted({p.parent for p in root.rglob("metadata.yaml")})
    files = sorted([*root.rglob("*.mcap"), *root.rglob("*.db3")])
    loose = [p for p in files if not any(f in p.parents for f in folders)]
    return folders + loose


@dataclass
class Checked:
    """What the checks found on one upstream bag."""

    outcomes: dict[str, str] = field(default_factory=dict)
    problems: list[str] = field(default_factory=list)


def check(bag: Path, work: Path) -> Checked:
    """info's counts against mcap's StreamReader, repair's verdict and the files' hashes, no traceback."""
    seen = Checked()
    work.mkdir(parents=True, exist_ok=True)
    target = work / bag.name
    if bag.is_dir():
        shutil.copytree(bag, target)
    else:
        shutil.copy2(bag, target)
    files = storage_files(target)
    sqlite = any(path.name.endswith(".db3") for path in files)
    messages: Counter[str] = Counter()
    times: list[int] = []
    found: list[Key] = []
    readable = True
    for path in files:
        try:
            readable_path = path
            if path.name.endswith(".zstd"):
                readable_path = work / "scratch.mcap"
                readable_path.write_bytes(file_bytes(path))
            found += sqlite_messages(readable_path) if sqlite else file_messages(readable_path)
        except Exception as error:  # the independent reader refuses it: not a valid bag by mcap / rosbags
            readable = False
            seen.outcomes["mcap"] = f"{'rosbags' if sqlite else 'mcap'} reader: {type(error).__name__}"
    messages.update(m.topic for m in found)
    times += [m.log_time for m in found]
    stale = metadata_disagrees(target, messages, times, files) if readable and files else ""
    before = hashes(target)
    info = smm_bag(["info", str(target)])
    repair = smm_bag(["repair", str(target)])
    after = hashes(target)
    if sqlite:
        seen.outcomes["info"] = f"{info.code} {(info.errors or ['ok'])[0][:200]}"
        check_sqlite(
            seen,
            target,
            work=work,
            found=found if readable else None,
            info=info,
            repair=repair,
            changed=before != after,
        )
        return seen
    for name, result in (("info", info), ("repair", repair)):
        seen.outcomes[name] = (
            f"{result.code} {(result.errors or result.stdout.splitlines()[-1:] or [''])[0][:200]}"
        )
        if result.traceback:
            seen.problems.append(f"{name} printed a traceback: {result.stderr[-1500:]}")
    if not files:  # another storage (sqlite3, ROS 1): one line naming it, its own exit code, nothing changed
        for name, result in (("info", info), ("repair", repair)):
            if result.code in (0, 8) or len(result.errors) != 1:
                seen.problems.append(
                    f"not MCAP: {name} must say so in one line: {result.code} {result.stderr}"[:400]
                )
        if after != before:
            seen.problems.append("repair changed a bag that is not MCAP")
        return seen
    if readable:
        total, topics = info_counts(info.stdout)
        if info.code != 0 or total != topic_messages(messages) or topics != messages:
            seen.problems.append(
                f"info: {info.code} {total} {dict(topics)} vs files {dict(messages)}; {info.stderr[-300:]}"
            )
        stored = {path.name for path in files}
        if stale:  # rebuilding metadata.yaml is right; the storage files stay as they were
            seen.outcomes["metadata.yaml"] = f"disagrees with the files ({stale})"
            before = {k: v for k, v in before.items() if k in stored}
            after = {k: v for k, v in after.items() if k in stored}
        if repair.code != 0 or after != before or "intact" not in repair.stdout:
            seen.problems.append(
                f"repair of a valid bag: exit {repair.code}, changed {after != before}: "
                f"{repair.stdout[-400:]} {repair.stderr[-300:]}"
            )
    return seen


def check_sqlite(
    seen: Checked,
    bag: Path,
    *,
    work: Path,
    found: list[Key] | None,
    info: Result,
    repair: Result,
    changed: bool,
) -> None:
    """A sqlite3 bag: info counts as rosbags' reader of each file; repair refuses in one line and changes
    nothing; convert gives an MCAP bag whose messages mcap's and rosbags' readers and info agree on."""
    for name, result in (("info", info), ("repair", repair)):
        if result.traceback:
            seen.problems.append(f"{name} printed a traceback: {result.stderr[-1500:]}")
    if repair.code != 9 or len(repair.errors) != 1 or changed:
        seen.problems.append(f"repair of sqlite3: {repair.code} {repair.stderr[-300:]}, changed {changed}")
    seen.outcomes["repair"] = f"{repair.code} {(repair.errors or [''])[0][:120]}"
    if found is None:
        return
    counts = Counter(m.topic for m in found)
    total, topics = info_counts(info.stdout)
    if info.code != 0 or total != topic_messages(counts) or +topics != +counts:
        seen.problems.append(f"info: {info.code} {total} {dict(topics)} vs files {dict(counts)}")
    converted = work / "converted"
    result = smm_bag(["convert", str(bag), str(converted)])
    seen.outcomes["convert"] = (
        f"{result.code} {(result.errors or result.stdout.splitlines()[-1:] or [''])[0][:120]}"
    )
    if result.code != 0 or result.traceback:
        seen.problems.append(f"convert: {result.code} {result.stderr[-600:]}")
        return
    mcap_read = Counter(m for path in storage_files(converted) for m in file_messages(path))
    if mcap_read != Counter(found):
        seen.problems.append(f"convert: mcap reads {sum(mcap_read.values())} of {len(found)} messages")
    try:
        from rosbags.rosbag2 import Reader

        with Reader(converted) as reader:
            by_rosbags = Counter(Key(c.topic, t, t, bytes(d)) for c, t, d in reader.messages())
        plain = Counter(Key(m.topic, m.log_time, m.log_time, m.data) for m in found)
        if by_rosbags != plain:
            seen.problems.append(
                f"convert: rosbags reads {sum(by_rosbags.values())} of {len(found)} messages"
            )
        seen.outcomes["rosbags"] = f"reads {sum(by_rosbags.values())}"
    except Exception as error:  # rosbags refuses what rosbag2 would too (a serialization other than cdr)
        seen.outcomes["rosbags"] = f"rosbags reader: {type(error).__name__}: {error}"[:160]
    again = smm_bag(["info", str(converted)])
    total, topics = info_counts(again.stdout)
    if again.code != 0 or total != topic_messages(counts) or +topics != +counts:
        seen.problems.append(f"info of the converted bag: {again.code} {total} {dict(topics)}")
    seen.outcomes["messages"] = f"{len(found)} ({topic_messages(counts)} on topics)"


def metadata_disagrees(folder: Path, counts: Counter[str], times: list[int], files: list[Path]) -> str:
    """What of a folder's metadata.yaml disagrees with its files (counts, time range, file list), or ""."""
    path = folder / "metadata.yaml"
    if not path.is_file():
        return ""
    info = yaml.safe_load(path.read_text())["rosbag2_bagfile_information"]
    listed = {t["topic_metadata"]["name"]: t["message_count"] for t in info["topics_with_message_count"]}
    if {k: v for k, v in listed.items() if v} != {k: v for k, v in counts.items() if v}:
        return "counts per topic"
    if info["message_count"] != sum(counts.values()):
        return "message count"
    if sorted(info["relative_file_paths"]) != sorted(p.name for p in files):
        return "file list"
    start, duration = info["starting_time"]["nanoseconds_since_epoch"], info["duration"]["nanoseconds"]
    if times and (start, duration) != (min(times), max(times) - min(times)):
        return "time range"
    return ""


def main(directory: str) -> int:
    """Prints each bag's outcomes and problems (``python tests/bag/corpus/upstream.py DIR``)."""
    import tempfile

    failed = 0
    for number, bag in enumerate(bags(directory)):
        with tempfile.TemporaryDirectory() as work:
            seen = check(bag, Path(work) / str(number))
        failed += bool(seen.problems)
        print(f"{bag.relative_to(directory)}: " + "; ".join(f"{k}: {v}" for k, v in seen.outcomes.items()))
        for problem in seen.problems:
            print(f"    PROBLEM {problem[:400]}")
    return 1 if failed else 0


if __name__ == "__main__":
    import sys

    sys.exit(main(sys.argv[1]))
