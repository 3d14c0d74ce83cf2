"""smm-bag repair on randomly damaged copies of real bags: the share of messages it keeps, per damage kind.

Run by ``make bench``. Damages ``--copies`` (500) copies of two real bags (the committed
``bags/sample_case2_fpdeso`` and a written bag of every recorded type, zstd chunks, split into files) at one
to three random places each (kinds: truncation, chunk bit flip, zeroed 4 KiB block, summary or footer,
metadata.yaml), runs ``smm-bag repair`` on each and checks the result message by message against the
original (tests/bag/repair_damage.py: no traceback, exit codes, "intact" only for files whose CRCs check,
every kept message equal to the original's, every message of an undamaged chunk kept, the bag readable by
rosbags and mcap with ``metadata.yaml`` equal to the files). Prints per kind the copies, the kept and lost
shares of the original messages, and the share of undamaged-chunk messages kept. Counts, not timings.
"""

from __future__ import annotations

import argparse
import random
import sys
import tempfile
from collections import defaultdict
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))

from bag.repair_damage import (  # type: ignore[import-not-found]  # noqa: E402
    KINDS,
    SAMPLE,
    damage_copy,
    random_places,
    read_original,
    repair_and_check,
    write_source_bag,
)


def main(argv: list[str] | None = None) -> int:
    """Runs the damaged copies and prints the table; exit 1 if any check failed."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--copies", type=int, default=500)
    parser.add_argument("--seed", type=int, default=21)
    options = parser.parse_args(argv)
    rng = random.Random(options.seed)
    rows: dict[str, list[int]] = defaultdict(lambda: [0, 0, 0, 0, 0, 0])
    failures = 0
    with tempfile.TemporaryDirectory() as directory:
        workdir = Path(directory)
        written = write_source_bag(workdir / "written")
        sources = [(written, read_original(written)), (SAMPLE, read_original(SAMPLE))]
        for copy in range(options.copies):
            source, originals = sources[copy % 2]
            places = random_places(rng)
            target = workdir / f"copy{copy}" / "bag"
            try:
                outcome = repair_and_check(source, originals, damage_copy(source, originals, target, places))
            except AssertionError as error:
                failures += 1
                print(f"copy {copy} ({source.name}, {places}): FAILED: {error}", flush=True)
                continue
            labels = [places[0].kind if len(places) == 1 else "several places", "all"]
            for label in labels:
                row = rows[label]
                row[0] += 1
                row[1] += outcome.original
                row[2] += outcome.kept
                row[3] += outcome.undamaged
                row[4] += outcome.intact_files
                row[5] += outcome.unsalvageable_files
            if (copy + 1) % 50 == 0:
                print(f"{copy + 1} copies done, {failures} failed", file=sys.stderr, flush=True)
            for path in sorted(target.parent.rglob("*"), reverse=True):
                path.unlink() if path.is_file() else path.rmdir()
    print(
        f"{'damage':20s} {'copies':>6s} {'messages':>9s} {'kept':>7s} {'lost':>7s} "
        f"{'of undamaged chunks kept':>24s} {'intact files':>12s} {'unsalvageable files':>19s}"
    )
    for label in [*KINDS, "several places", "all"]:
        copies, original, kept, undamaged, intact, lost_files = rows[label]
        if copies:
            print(
                f"{label:20s} {copies:6d} {original:9d} {kept / original:7.2%} {1 - kept / original:7.2%} "
                f"{undamaged:>15d} (100%) {intact:12d} {lost_files:19d}"
            )
    print(f"{failures} of {options.copies} copies failed a check")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
