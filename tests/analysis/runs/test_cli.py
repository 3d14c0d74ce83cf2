"""smm_analysis's entry points give ``smm-bag`` its ``analyze`` and ``rerun`` subcommands."""

from __future__ import annotations

import argparse

from smm_bag import cli


def test_the_installed_analysis_subcommands_are_found() -> None:
    subcommands = next(
        action for action in cli.build_parser()._actions if isinstance(action, argparse._SubParsersAction)
    )
    assert {"info", "play", "repair", "analyze", "rerun"} <= set(subcommands.choices)
