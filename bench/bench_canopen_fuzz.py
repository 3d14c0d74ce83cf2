"""Random frames on the CANopen link's bus for a set time, the oracle of docs/HW_CANOPEN.md checked.

Duration: SMM_CANOPEN_FUZZ_S seconds (default 60); seed: SMM_CANOPEN_FUZZ_SEED (default 1). Prints the
episodes, frames, faults by kind and every violation of the oracle; exits 1 if there was one (not timing).
"""

from __future__ import annotations

import collections
import os
import random
import re
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))

from hw_bridge.canopen_fuzz import LINK_IDS, Injection, run_episode  # type: ignore[import-not-found]


def _injection(rng: random.Random) -> Injection:
    data = bytes(rng.randrange(256) for _ in range(rng.randrange(9)))
    ident = rng.choice(LINK_IDS) if rng.random() < 0.7 else rng.randrange(0x800)
    return Injection(rng.randrange(6), ident, data, extended=rng.random() < 0.1, remote=rng.random() < 0.1)


def main() -> int:
    seconds = float(os.environ.get("SMM_CANOPEN_FUZZ_S", "60"))
    rng = random.Random(int(os.environ.get("SMM_CANOPEN_FUZZ_SEED", "1")))
    kinds: collections.Counter[str] = collections.Counter()
    episodes = frames = changing = 0
    violations: list[str] = []
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        injections = [_injection(rng) for _ in range(rng.randrange(1, 7))]
        codes = [(rng.randrange(-20_000, 20_001), rng.randrange(-20_000, 20_001)) for _ in range(6)]
        outcome = run_episode(injections, codes)
        episodes += 1
        frames += len(injections)
        changing += any(i.changes_state for i in injections)
        for fault in outcome.faults:
            kinds[re.sub(r"\[[^]]*\]|0x[0-9A-F]+|\d+", "#", fault.split(": ", 1)[1])] += 1
        violations += [f"episode {episodes}: {v} ({injections})" for v in outcome.violations]
    print(
        f"canopen fuzz: {episodes} episodes, {frames} foreign frames, {changing} episodes with a frame only "
        f"a master sends, {seconds:g} s; violations of the oracle: {len(violations)}"
    )
    for kind, count in kinds.most_common(12):
        print(f"  fault {count:6d}  {kind}")
    for violation in violations[:20]:
        print(f"  VIOLATION {violation}")
    return 1 if violations else 0


if __name__ == "__main__":
    sys.exit(main())
