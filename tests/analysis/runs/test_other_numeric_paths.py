"""The sample-bag rerun under other numeric paths of this machine, in subprocesses, so that CI shows what
another CPU would (docs/TESTING.md, "Floats across machines"; ``make test-other-cpu`` runs every
``cross_machine`` test this way)."""

from __future__ import annotations

import platform

import pytest
from numeric_paths import PATHS, PathResult, rerun_sample

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(platform.machine() != "x86_64", reason="the switches name x86-64 kernels"),
]


@pytest.fixture(scope="module")
def results() -> dict[str, PathResult]:
    return {name: rerun_sample(path) for name, path in {"default": {}, **PATHS}.items()}


@pytest.mark.parametrize("name", ["default", *PATHS])
def test_the_sample_bag_reproduces_under(results: dict[str, PathResult], name: str) -> None:
    result = results[name]
    assert result.returncode == 0, result.stderr
    assert result.summary["reproduces_recording"] is True


def test_the_forced_paths_change_the_last_bits_here(results: dict[str, PathResult]) -> None:
    kernels = {results[name].openblas_core for name in ("openblas-haswell", "openblas-sse")}
    assert len(kernels) == 2, f"OPENBLAS_CORETYPE did not change the kernel: {kernels}"
    differences = {results[name].max_command_difference for name in ("openblas-haswell", "openblas-sse")}
    assert len(differences) == 2, "two OpenBLAS kernels gave the same commands"
    assert max(differences) > 0.0  # so bit for bit would fail here: the default tolerance is what passes
