"""Offline closed-loop reproduction of the FPDESO paper, metrics and bag analysis."""
