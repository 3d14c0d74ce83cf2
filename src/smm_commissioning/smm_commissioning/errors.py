"""Typed errors of the commissioning steps: each says what is wrong in words a technician acts on."""

from __future__ import annotations

__all__ = ["BenchFaultError", "CommissioningError", "LinkLostError", "MotionStopError", "StepOrderError"]


class CommissioningError(Exception):
    """A step cannot go on; the bench has been left disabled."""


class StepOrderError(CommissioningError):
    """A step was asked for before the step it needs passed (the state file of ``--out``)."""


class LinkLostError(CommissioningError):
    """No feedback from the board within the timeout, or the board restarted during a step."""


class BenchFaultError(CommissioningError):
    """``probe`` found faults; ``findings`` names each one.

    Args:
        findings: One sentence per fault, what is wrong and what to check.
    """

    def __init__(self, findings: list[str]) -> None:
        super().__init__("; ".join(findings))
        self.findings = findings


class MotionStopError(CommissioningError):
    """``jog`` stopped a joint on something unexpected (window, speed, no response, no counting)."""
