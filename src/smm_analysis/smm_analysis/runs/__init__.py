"""Recorded runs: a bag's per-step arrays, their indices, figures, report and offline re-run."""
