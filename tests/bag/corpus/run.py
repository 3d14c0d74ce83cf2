"""Runs ``smm-bag`` on a corpus entry and classifies what it did (exit code, class), with the evidence.

Commands run in-process (``smm_bag.cli.main``) or as the installed CLI (``subprocess=True``). Counts are
compared with an independent reader; repair's files are hashed before and after.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import re
import shutil
import struct
import subprocess
import sys
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import zstandard
from bag.corpus import mcap_bytes as mb
from bag.corpus.entries import SKIP, Entry, Outcome
from bag.corpus.sample import SAMPLE, Key, file_messages

SMM_BAG = Path(sys.executable).parent / "smm-bag"
EXIT_NAMES = {
    3: "not a bag",
    4: "truncated",
    5: "corrupt",
    6: "missing topics",
    7: "bad parameters",
    8: "unsalvageable",
    9: "other storage",
}


@dataclass
class Result:
    """What one command printed and returned."""

    code: int
    stdout: str
    stderr: str

    @property
    def traceback(self) -> bool:
        return "Traceback (most recent call last)" in self.stderr + self.stdout

    @property
    def errors(self) -> list[str]:
        return [line for line in self.stderr.splitlines() if line.startswith("smm-bag: error:")]


def smm_bag(args: list[str], *, subprocess_call: bool = False) -> Result:
    """``smm-bag ARGS``: the installed CLI in a subprocess, or ``smm_bag.cli.main`` in this process."""
    if subprocess_call:
        done = subprocess.run([str(SMM_BAG), *args], capture_output=True, text=True, timeout=600, check=False)
        return Result(done.returncode, done.stdout, done.stderr)
    from smm_bag.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(args)
        except SystemExit as exit_:
            code = exit_.code if isinstance(exit_.code, int) else 2
        except Exception:  # a traceback is an outcome of its own
            import traceback

            traceback.print_exc(file=err)
            code = -2
    return Result(code, out.getvalue(), err.getvalue())


# ---------------------------------------------------------------------------------- independent reading


def storage_files(bag: Path) -> list[Path]:
    """The storage files of a bag folder (repair backups excluded), or the bare file itself."""
    if bag.is_file():
        return [bag]
    return sorted(p for p in bag.iterdir() if p.name.endswith((".mcap", ".mcap.zstd", ".db3")))


def sqlite_messages(path: Path) -> list[Key]:
    """Every message of one sqlite3 file, by rosbags' reader of that file alone (apsw, not our sqlite3)."""
    from rosbags.rosbag2 import Reader

    with Reader(path) as reader:
        return [Key(c.topic, stamp, stamp, bytes(data)) for c, stamp, data in reader.messages()]


def file_bytes(path: Path) -> bytes:
    data = path.read_bytes()
    return (
        zstandard.ZstdDecompressor().decompressobj().decompress(data) if path.name.endswith(".zstd") else data
    )


def independent_messages(bag: Path, padded_chunks: bool = False) -> list[mb.Message]:
    """Every message of the bag's files: mcap's StreamReader over every record (the byte reader for padded
    chunk records, which mcap 1.6.0's StreamReader misreads)."""
    found: list[mb.Message] = []
    for path in storage_files(bag):
        if path.name.endswith(".db3"):
            found += sqlite_messages(path)
        elif padded_chunks or path.name.endswith(".zstd"):
            found += mb.sequential_read(file_bytes(path)).messages
        else:
            found += file_messages(path)
    return found


def hashes(bag: Path) -> dict[str, str]:
    """SHA-256 of every file of the bag's folder (the folder holding a bare file)."""
    folder = bag if bag.is_dir() else bag.parent
    return {
        p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir()) if p.is_file()
    }


_TOPIC = re.compile(r"Topic: (\S+) \| Type: \S+ \| Count: (\d+)")
_SERVICE = re.compile(r"Service: (\S+) \| Type: \S+ \| Event Count: (\d+)")


def topic_messages(counts: Counter[str]) -> int:
    """What ``ros2 bag info`` prints as ``Messages:``: the messages of topics that are not service events."""
    return sum(n for topic, n in counts.items() if not topic.endswith("/_service_event"))


def info_counts(text: str) -> tuple[int | None, Counter[str]]:
    """``Messages:`` and the count per topic (a service's events on its ``/_service_event`` topic)."""
    total = re.search(r"^Messages:\s+(\d+)", text, re.MULTILINE)
    counts = Counter({t: int(n) for t, n in _TOPIC.findall(text)})
    counts.update({f"{s}/_service_event": int(n) for s, n in _SERVICE.findall(text)})
    return (int(total.group(1)) if total else None), counts


# ------------------------------------------------------------------------------------------- damage


def damage(bag: Path, kind: str) -> Path:
    """Damages the first storage file of ``bag`` in place; returns it."""
    path = storage_files(bag)[0]
    data = bytearray(path.read_bytes())
    records = list(mb.iter_records(bytes(data)))
    data_end = next(offset for offset, opcode, _ in records if opcode == mb.DATA_END)
    if kind == "cut-mid":
        data = data[: data_end * 9 // 20]
    elif kind == "cut-summary":
        footer = next(offset for offset, opcode, _ in records if opcode == mb.FOOTER)
        data = data[: (data_end + footer) // 2 + 1] if footer - data_end > 20 else data[: len(data) - 20]
    elif kind in ("length", "opcode"):
        body = [offset for offset, opcode, _ in records if opcode in (mb.CHUNK, mb.MESSAGE)]
        target = body[len(body) // 2]
        if kind == "length":
            data[target + 1 : target + 9] = struct.pack("<Q", 0x7FFF_FFFF_FFFF_0000)
        else:
            data[target] = 0
    else:
        raise ValueError(kind)
    path.write_bytes(bytes(data))
    return path


# ----------------------------------------------------------------------------------------- running


@dataclass
class Observed:
    """The outcome of each command on one entry, and why."""

    outcomes: dict[str, Outcome] = field(default_factory=dict)
    notes: dict[str, str] = field(default_factory=dict)
    tracebacks: list[str] = field(default_factory=list)


def _error_class(result: Result) -> str:
    if result.traceback or result.code == -2:
        return "traceback"
    return EXIT_NAMES.get(result.code, "error")


def _note(result: Result) -> str:
    return (
        result.errors[:1]
        or result.stderr.strip().splitlines()[-1:]
        or result.stdout.strip().splitlines()[-1:]
        or [""]
    )[0][:300]


def metrics_values(document: dict[str, Any]) -> str:
    """metrics.json without what names the bag (its path) or comes from its manifest, as JSON text (floats
    as their shortest repr: equal text is equal bits, NaN included)."""
    meta = document.get("meta", {})
    bags = list(meta.get("bags", {}).values())
    numbers = [value for key, value in document.items() if key != "meta"]
    flat = [controllers for scenario in numbers for controllers in scenario.values()]
    ignore = {"scenario", "controller", "seed", "plant", "version"}
    kept = [{k: v for k, v in bag.items() if k not in ignore} for bag in bags]
    return json.dumps([flat, kept], sort_keys=True)


def run_entry(
    entry: Entry, bag: Path, work: Path, original_metrics: Any, *, subprocess_call: bool
) -> Observed:
    """Every command of the corpus on ``bag`` (built, pristine; copied before anything may change it)."""
    seen = Observed()

    def record(command: str, result: Result, outcome: Outcome, note: str = "") -> None:
        if result.traceback:
            seen.tracebacks.append(f"{command}: {result.stderr[-2000:]}")
        seen.outcomes[command] = outcome
        seen.notes[command] = note or _note(result)

    target = _copy(bag, work / "run")
    if entry.damage:
        damaged_bytes = file_bytes(damage(target, entry.damage))
        expected = mb.sequential_read(damaged_bytes).messages
        spare = _copy(target, work / "no-backup")
    else:
        expected = independent_messages(target, entry.padded_chunks)
    before = hashes(target)

    info = smm_bag(["info", str(target)], subprocess_call=subprocess_call)
    if info.code == 0:
        total, topics = info_counts(info.stdout)
        want = Counter(m.topic for m in expected)
        good = total == topic_messages(want) and topics == want
        record(
            "info",
            info,
            (0, "ok" if good else "counts differ"),
            "" if good else f"info {total} {dict(topics)} vs files {len(expected)} {dict(want)}",
        )
    else:
        record("info", info, (info.code, _error_class(info)))

    if entry.expect.get("analyze", SKIP) != SKIP:
        out = work / "analyze"
        result = smm_bag(
            ["analyze", str(target), "--out", str(out), "--no-plots", "--quiet"],
            subprocess_call=subprocess_call,
        )
        if result.code == 0 and (out / "metrics.json").is_file():
            same = metrics_values(json.loads((out / "metrics.json").read_text())) == original_metrics
            record("analyze", result, (0, "same metrics" if same else "other metrics"))
        elif result.code != 0 and not result.traceback and len(result.errors) == 1 and result.code == 6:
            record("analyze", result, (6, "not the stack's topics"))
        else:
            record("analyze", result, (result.code, _error_class(result)))
    if entry.expect.get("rerun", SKIP) != SKIP:
        result = smm_bag(["rerun", str(target), "--expect-equal"], subprocess_call=subprocess_call)
        record(
            "rerun",
            result,
            (0, "reproduces")
            if result.code == 0
            else (result.code, _error_class(result) if result.code != 1 else "differs"),
        )

    if hashes(target) != before:
        seen.notes["read-only"] = "a reading command changed the bag's files"
        seen.outcomes["info"] = (seen.outcomes["info"][0], "changed files")

    repaired = smm_bag(["repair", str(target)], subprocess_call=subprocess_call)
    after = hashes(target)
    if entry.damage:
        kept = independent_messages(target, entry.padded_chunks) if repaired.code == 0 else []
        missing = Counter(expected) - Counter(kept)
        alone = smm_bag(["repair", "--no-backup", str(spare)])
        kept_alone = independent_messages(spare, entry.padded_chunks) if alone.code == 0 else []
        if alone.code != repaired.code or Counter(kept_alone) != Counter(kept):
            record(
                "repair",
                alone,
                (alone.code, "--no-backup kept less"),
                f"--no-backup kept {len(kept_alone)}, with backups {len(kept)}",
            )
        elif repaired.code == 0 and not missing:
            record(
                "repair",
                repaired,
                (0, "repaired"),
                f"kept {len(kept)} of the {len(expected)} a sequential read gives",
            )
        else:
            cls = _error_class(repaired) if repaired.code else f"lost {sum(missing.values())}"
            record(
                "repair",
                repaired,
                (repaired.code, cls),
                f"kept {len(kept)}, {sum(missing.values())} of the sequential read's {len(expected)} "
                f"missing; {_note(repaired)}",
            )
    elif (
        repaired.code == 0
        and after == before
        and "intact" in repaired.stdout
        and "damaged" not in repaired.stdout
    ):
        record("repair", repaired, (0, "intact"))
    else:
        changed = sorted(set(before.items()) ^ set(after.items()))
        cls = (
            "changed files" if after != before else _error_class(repaired) if repaired.code else "not intact"
        )
        record(
            "repair",
            repaired,
            (repaired.code, cls),
            f"{_note(repaired)}; changed: {[name for name, _ in changed][:6]}",
        )
    return seen


def _copy(bag: Path, to: Path) -> Path:
    shutil.rmtree(to, ignore_errors=True)
    if bag.is_dir():
        shutil.copytree(bag, to)
        return to
    to.mkdir(parents=True)
    shutil.copy2(bag, to / bag.name)
    return to / bag.name


def original_metrics(work: Path) -> Any:
    """metrics.json values of the committed sample (the reference every SMM rewrite must equal)."""
    result = smm_bag(
        ["analyze", str(_copy(SAMPLE, work / "sample")), "--out", str(work / "out"), "--no-plots", "--quiet"]
    )
    if result.code != 0:
        raise RuntimeError(f"analyze of the sample failed: {result.stderr}")
    return metrics_values(json.loads((work / "out" / "metrics.json").read_text()))
