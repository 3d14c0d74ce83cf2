"""The stack's config schema, below every other package: ranges of config fields and config <-> parameters.

:mod:`smm_schema.ranges`: a numeric field's range as field metadata and the checks every config shares;
:mod:`smm_schema.fields`: a config dataclass as flat parameter values (kinds, ranges, descriptions,
conversions), without ROS. Pure Python; imports nothing of the stack (docs/DESIGN.md, "Ranges of config
fields").
"""
