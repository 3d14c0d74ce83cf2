"""Bags of an external directory (rosbag2's test bags, the MCAP conformance files): never committed here.

``make test-bags UPSTREAM=DIR`` runs the corpus checks over every bag folder (one with metadata.yaml) and
every bare ``.mcap`` file outside such folders under DIR.
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

from bag.corpus.run import file_bytes, hashes, info_counts, smm_bag, storage_files, topic_messages
from bag.corpus.sample import file_messages


def bags(directory: str) -> list[Path]:
    """Bag folders and bare MCAP files under ``directory`` ("" or missing: none)."""
    if not directory or not Path(directory).is_dir():
        return []
    root = Path(directory)
    folders = sorted({p.parent for p in root.rglob("metadata.yaml")})
    loose = [p for p in sorted(root.rglob("*.mcap")) if not any(f in p.parents for f in folders)]
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
    messages: Counter[str] = Counter()
    times: list[int] = []
    readable = True
    for path in files:
        try:
            readable_path = path
            if path.name.endswith(".zstd"):
                readable_path = work / "scratch.mcap"
                readable_path.write_bytes(file_bytes(path))
            found = file_messages(readable_path)
            messages.update(m.topic for m in found)
            times += [m.log_time for m in found]
        except Exception as error:  # the independent reader refuses it: not a valid bag by mcap
            readable = False
            seen.outcomes["mcap"] = f"mcap reader: {type(error).__name__}"
    stale = metadata_disagrees(target, messages, times, files) if readable and files else ""
    before = hashes(target)
    info = smm_bag(["info", str(target)])
    repair = smm_bag(["repair", str(target)])
    after = hashes(target)
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
