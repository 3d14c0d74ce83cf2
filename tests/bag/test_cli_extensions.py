"""Other packages add subcommands to ``smm-bag`` (entry points); a broken one leaves the rest working."""

from __future__ import annotations

import argparse
from importlib.metadata import EntryPoint
from pathlib import Path

import pytest

from smm_bag import cli

SAMPLE = Path(__file__).resolve().parents[2] / "bags" / "sample_case2_fpdeso"


def add_hello(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser("hello")
    parser.add_argument("--code", type=int, default=0)
    parser.set_defaults(handler=lambda options: options.code)


def _group(*entries: EntryPoint) -> object:
    def entry_points(group: str) -> tuple[EntryPoint, ...]:
        assert group == cli.COMMAND_GROUP
        return entries

    return entry_points


def test_an_entry_point_adds_a_subcommand(monkeypatch: pytest.MonkeyPatch) -> None:
    hello = EntryPoint("hello", f"{__name__}:add_hello", cli.COMMAND_GROUP)
    monkeypatch.setattr(cli, "entry_points", _group(hello))
    assert cli.main(["hello", "--code", "5"]) == 5
    assert cli.main(["info", str(SAMPLE)]) == 0


def test_a_broken_entry_point_is_named_and_the_others_still_run(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    broken = EntryPoint("broken", "smm_no_such_package.cli:add", cli.COMMAND_GROUP)
    monkeypatch.setattr(cli, "entry_points", _group(broken))
    assert cli.main(["info", str(SAMPLE)]) == 0
    assert "subcommand 'broken' unavailable" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        cli.main(["broken"])
