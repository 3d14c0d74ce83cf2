"""Other numeric paths on this machine: the switches that make numpy, OpenBLAS and libm compute as on
another x86-64 CPU, and the sample-bag rerun under each (docs/TESTING.md, "Floats across machines").

``python tests/numeric_paths.py [PYTEST ARGS]`` (``make test-other-cpu``) prints, per path, the OpenBLAS
kernel in use and the rerun's largest command difference against the committed sample bag, then runs
pytest with PYTEST ARGS (default: the ``cross_machine`` tests) under each path in a subprocess.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SAMPLE = REPO / "bags" / "sample_case2_fpdeso"

#: Name -> environment of each forced path. OpenBLAS falls back to a kernel the CPU runs (SkylakeX needs
#: AVX-512, Haswell AVX2; Prescott is the SSE kernel every x86-64 runs); numpy refuses to go below its
#: baseline (X86_V2); glibc ignores a feature the CPU lacks.
PATHS: Mapping[str, Mapping[str, str]] = {
    "openblas-skylakex": {"OPENBLAS_CORETYPE": "SkylakeX"},
    "openblas-haswell": {"OPENBLAS_CORETYPE": "Haswell"},
    "openblas-sse": {"OPENBLAS_CORETYPE": "Prescott"},
    "numpy-baseline": {"NPY_DISABLE_CPU_FEATURES": "X86_V3 X86_V4 AVX512_ICL"},
    "libm-no-fma": {"GLIBC_TUNABLES": "glibc.cpu.hwcaps=-AVX2,-FMA,-AVX512F"},
    "all-generic": {
        "OPENBLAS_CORETYPE": "Prescott",
        "NPY_DISABLE_CPU_FEATURES": "X86_V3 X86_V4 AVX512_ICL",
        "GLIBC_TUNABLES": "glibc.cpu.hwcaps=-AVX2,-FMA,-AVX512F",
    },
}

_CORE = (
    "import ctypes, glob, os, numpy\n"
    "libs = glob.glob(os.path.join(os.path.dirname(numpy.__path__[0]), 'numpy.libs', '*openblas*'))\n"
    "names = ('scipy_openblas_get_corename64_', 'scipy_openblas_get_corename', 'openblas_get_corename')\n"
    "lib = ctypes.CDLL(libs[0]) if libs else None\n"
    "found = [getattr(lib, n) for n in names if lib is not None and hasattr(lib, n)]\n"
    "if found: found[0].restype = ctypes.c_char_p\n"
    "print(found[0]().decode() if found else 'unknown')\n"
)


@dataclass(frozen=True)
class PathResult:
    """The sample-bag rerun under one path: exit code of ``--expect-equal``, its JSON summary, the kernel."""

    returncode: int
    summary: Mapping[str, object]
    openblas_core: str
    stderr: str

    @property
    def max_command_difference(self) -> float:
        """Largest |offline - recorded| command over both joints (N m)."""
        values = self.summary["command_max_abs_difference_Nm"]
        assert isinstance(values, list)
        return max(float(value) for value in values)


def environment(path: Mapping[str, str]) -> dict[str, str]:
    """This process's environment with ``path``'s switches set."""
    return {**os.environ, **path}


def rerun_sample(path: Mapping[str, str], *extra: str) -> PathResult:
    """``smm-bag rerun SAMPLE --expect-equal --json`` in a subprocess under ``path``."""
    env = environment(path)
    done = subprocess.run(
        [sys.executable, "-m", "smm_bag.cli", "rerun", str(SAMPLE), "--expect-equal", "--json", *extra],
        capture_output=True,
        text=True,
        env=env,
        check=False,
        timeout=300,
    )
    core = subprocess.run(
        [sys.executable, "-c", _CORE], capture_output=True, text=True, env=env, check=True, timeout=60
    )
    summary = json.loads(done.stdout) if done.stdout.strip() else {}
    return PathResult(done.returncode, summary, core.stdout.strip(), done.stderr)


def main(pytest_args: list[str]) -> int:
    """Prints the rerun under every path, then runs pytest under every path; 0 when every run passed."""
    print(f"{'path':<18} {'OpenBLAS':<10} {'max |du| (N m)':>16} {'flips':>6}  verdict")
    worst = 0
    for name, path in {"default": {}, **PATHS}.items():
        result = rerun_sample(path)
        verdict = "reproduces" if result.returncode == 0 else f"FAILS (exit {result.returncode})"
        flips = result.summary.get("sign_flips", "?")
        difference = result.max_command_difference
        print(f"{name:<18} {result.openblas_core:<10} {difference:>16.3g} {flips!s:>6}  {verdict}")
        worst = max(worst, result.returncode)
    for name, path in PATHS.items():
        switches = " ".join(f"{key}={value}" for key, value in path.items())
        print(f"\n== pytest {' '.join(pytest_args)} under {name}: {switches}")
        sys.stdout.flush()
        done = subprocess.run(
            [sys.executable, "-m", "pytest", *pytest_args], cwd=REPO, env=environment(path), check=False
        )
        worst = max(worst, done.returncode)
    return worst


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:] or ["tests", "-m", "cross_machine", "-q"]))
