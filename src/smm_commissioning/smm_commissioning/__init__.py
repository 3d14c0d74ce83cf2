"""Guided commissioning of the bench: probe, jog (and the later steps), each a pure step over a Device."""
