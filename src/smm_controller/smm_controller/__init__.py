"""FPDESO controller of the SMM: TD, fuzzy PD, FLESO, robust term, baselines, and their nodes."""
