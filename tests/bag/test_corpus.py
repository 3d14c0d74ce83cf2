"""Bags this stack did not write (issue 29): every corpus entry gives its expected outcome per command.

The corpus is generated at test time (tests/bag/corpus); ``make test`` runs the fast entries,
``make test-bags`` all of them (``SMM_BAG_CORPUS=full``) and, with ``UPSTREAM=DIR`` (environment
``SMM_BAG_UPSTREAM``), every bag found under DIR (rosbag2's test bags, the conformance files: never
committed here). docs/BAGS.md, "Bags of other writers".
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from bag.corpus import table, upstream
from bag.corpus.entries import SHOWN, SKIP, Entry, entries, selected
from bag.corpus.run import Observed, original_metrics, run_entry, smm_bag

# One worker: the session's Corpus builds and runs each entry once, and the table test observes every entry.
pytestmark = [pytest.mark.slow, pytest.mark.xdist_group("bag_corpus")]

ENTRIES = selected()
SUBPROCESS = {"mcap-unchunked", "rosbags-file", "js-default", "shape-other-topics", "mcap-unchunked+length"}
"""Entries run through the installed ``smm-bag`` (the rest in-process, faster)."""


class Corpus:
    """Builds each entry once per session, runs its commands once, keeps what was seen."""

    def __init__(self, root: Path) -> None:
        self.root = root
        self._metrics: Any = None
        self._built: dict[str, Path] = {}
        self.observed: dict[str, Observed] = {}

    def metrics(self) -> Any:
        if self._metrics is None:
            self._metrics = original_metrics(self.root / "original")
        return self._metrics

    def bag(self, entry: Entry) -> Path:
        base = entry.name.split("+")[0] + ("+folder" if entry.damage else "")
        if base not in self._built:
            self._built[base] = entry.build(self.root / "built" / base)
        return self._built[base]

    def observe(self, entry: Entry) -> Observed:
        if entry.name not in self.observed:
            needs_metrics = entry.expect.get("analyze", SKIP) != SKIP
            self.observed[entry.name] = run_entry(
                entry,
                self.bag(entry),
                self.root / "work" / entry.name,
                self.metrics() if needs_metrics else None,
                subprocess_call=entry.name in SUBPROCESS,
            )
        return self.observed[entry.name]


@pytest.fixture(scope="session")
def corpus(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Corpus]:
    yield Corpus(tmp_path_factory.mktemp("corpus"))


@pytest.mark.parametrize("entry", ENTRIES, ids=[entry.name for entry in ENTRIES])
def test_corpus_entry_outcome(corpus: Corpus, entry: Entry) -> None:
    seen = corpus.observe(entry)
    assert not seen.tracebacks, "\n".join(seen.tracebacks)
    wanted = {command: outcome for command, outcome in entry.expect.items() if outcome not in (SKIP, SHOWN)}
    got = {command: seen.outcomes.get(command) for command in wanted}
    assert got == wanted, {
        command: seen.notes.get(command) for command in wanted if got[command] != wanted[command]
    }


UPSTREAM_DIR = os.environ.get("SMM_BAG_UPSTREAM", "")
if UPSTREAM_DIR:  # only with make test-bags UPSTREAM=DIR: the bags are not in this repository
    UPSTREAM = upstream.bags(UPSTREAM_DIR)
    if not UPSTREAM:
        raise pytest.UsageError(f"SMM_BAG_UPSTREAM={UPSTREAM_DIR}: no bag folder or .mcap file under it")

    @pytest.mark.parametrize("bag", UPSTREAM, ids=[str(bag) for bag in UPSTREAM])
    def test_upstream_bag(bag: Path, tmp_path: Path) -> None:
        """A bag of an external directory: info counts what its files hold, repair leaves it as it was."""
        seen = upstream.check(bag, tmp_path)
        assert seen.problems == [], seen.problems


def test_one_error_line_when_the_topics_are_not_the_stacks(corpus: Corpus) -> None:
    entry = next(e for e in ENTRIES if e.name == "shape-other-topics")
    result = smm_bag(["analyze", str(corpus.bag(entry))])
    assert result.code != 0
    assert len(result.errors) == 1 and not result.traceback, result.stderr


def test_committed_table_matches_the_corpus(corpus: Corpus) -> None:
    """docs/BAGS.md's writer x command table holds, for every entry run here, what the corpus gave (the
    ``shape-*`` row only when every shape ran)."""
    committed = table.committed_rows()
    observed = [(entry, corpus.observe(entry).outcomes) for entry in ENTRIES]
    every_shape = sum(table.grouped(e) for e in ENTRIES) == sum(table.grouped(e) for e in entries())
    differing = {}
    for line in table.rows(observed):
        name = line.split("`")[1]
        if (name != table.SHAPES or every_shape) and committed.get(name) != line:
            differing[name] = (committed.get(name), line)
    assert not differing, f"run `make corpus-table` (tests/bag/corpus/table.py): {differing}"
