"""Bags this stack did not write, generated at test time (docs/BAGS.md, "Bags of other writers")."""
