"""A sweep specification (YAML, format in docs/SWEEPS.md) and the runs it stands for.

Every value is validated by building the config it belongs to, naming the spec field. Run id = (gain set
x plant draws + plant draw) x scenarios + scenario.
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from scipy.stats import qmc
from smm_controller.laws import PAPER_LAWS, law_names, law_table
from smm_controller.limits import OutputLimitConfig
from smm_node_runtime.parameter_check import did_you_mean
from smm_schema.fields import config_fields, config_from_parameters, config_to_parameters

from smm_analysis.batch.loop import INDEX_NAMES, RunSettings
from smm_analysis.closed_loop import scenario_plant_config
from smm_analysis.errors import AnalysisError, UnknownScenarioError
from smm_analysis.reproduction.acceptance import (
    CASE2_RMS_REDUCTION,
    STEP_OVERSHOOT_LIMIT,
    STEP_RISE_TIME_RANGE,
)
from smm_analysis.scenarios import Scenario, get_scenario
from smm_controller import FLESOConfig, TrackingDifferentiatorConfig
from smm_dynamics import SMMParameters
from smm_sim.config import PlantParameters

__all__ = ["ParameterValues", "SpecError", "SweepSpec", "load_spec", "parse_spec"]

ParameterValues = dict[str, Any]
"""``{parameter name: value}`` with names as the nodes declare them (``name[j]`` for one joint)."""

STATISTICS = ("p50", "p95", "worst")
_OPERATORS = ("<", "<=", ">", ">=")
_SAMPLING = ("random", "lhs")
_INDEXED = re.compile(r"^(?P<name>[A-Za-z_][\w.]*)(\[(?P<joint>[01])\])?$")
_PLANT_REFUSED = {
    "control_period": "the sweep's control period is the controller's",
    "initial_position": "the offline loop starts at rest at q = 0",
}


class SpecError(AnalysisError):
    """A sweep spec is invalid; the message names the field."""


@dataclass(frozen=True)
class Constraint:
    """``index op bound``; bound a number, or the least (``<``) / greatest (``>``) index of reference laws.

    Attributes:
        column: ``scenario.index`` the constraint is on.
        op: One of ``<``, ``<=``, ``>``, ``>=``.
        value: A fixed bound, or None when ``controllers`` gives it.
        controllers: Laws whose paper-gain run of the same scenario gives the bound.
        factor: Factor on the laws' bound.
    """

    column: str
    op: str
    value: float | None
    controllers: tuple[str, ...] = ()
    factor: float = 1.0

    def text(self) -> str:
        """The constraint in words."""
        if self.value is not None:
            return f"{self.column} {self.op} {self.value:g}"
        scaled = "" if self.factor == 1.0 else f"{self.factor:g} x "
        return f"{self.column} {self.op} {scaled}best of {'/'.join(self.controllers)} (paper gains)"


@dataclass(frozen=True)
class SweepSpec:
    """A validated sweep spec (see the module docstring).

    Attributes:
        name: Sweep name.
        controller: Law of every run.
        scenarios: Scenarios every gain set runs.
        gain_sets: Per gain set, the varied controller parameter values.
        varied: Names of the varied controller parameters, in spec order.
        fixed: Controller parameters fixed for every run.
        plant_fixed: Plant parameters fixed for every run.
        plant_draws: Per plant draw, the drawn plant parameter values (one empty draw if none).
        objectives: Columns ``scenario.index`` to minimise.
        statistic: Statistic over the plant draws the front and the selection use.
        constraints: Constraints on a gain set's statistic.
        select: Column to minimise when choosing one gain set.
        batch_size: Runs per task.
        source: The spec as loaded (for the output folder and ``--rerun``).
    """

    name: str
    controller: str
    scenarios: tuple[Scenario, ...]
    gain_sets: tuple[ParameterValues, ...]
    varied: tuple[str, ...]
    fixed: ParameterValues
    plant_fixed: ParameterValues
    plant_draws: tuple[ParameterValues, ...]
    objectives: tuple[str, ...]
    statistic: str
    constraints: tuple[Constraint, ...]
    select: str
    batch_size: int
    source: Mapping[str, Any]
    _built: dict[tuple[int, int, int], RunSettings] = dataclasses.field(
        default_factory=dict, repr=False, compare=False
    )

    @property
    def run_count(self) -> int:
        """Number of runs."""
        return len(self.gain_sets) * len(self.plant_draws) * len(self.scenarios)

    @property
    def digest(self) -> str:
        """Hash of the spec's content: an output folder resumes only the same spec."""
        text = json.dumps(self.source, sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def locate(self, run_id: int) -> tuple[int, int, int]:
        """(gain set, plant draw, scenario) of a run id."""
        if not 0 <= run_id < self.run_count:
            raise SpecError(f"run id {run_id} is not in this sweep (0 .. {self.run_count - 1})")
        rest, scenario = divmod(run_id, len(self.scenarios))
        gain_set, draw = divmod(rest, len(self.plant_draws))
        return gain_set, draw, scenario

    def settings(self, run_id: int) -> RunSettings:
        """The run's settings."""
        gain_set, draw, scenario = self.locate(run_id)
        # Building configs costs milliseconds: a gain set's controller side is built once, and so is each
        # plant draw's plant per scenario; a run combines the two.
        law_key = (gain_set, -1, -1)
        plant_key = (-1, draw, scenario)
        if law_key not in self._built:
            controller = {**self.fixed, **self.gain_sets[gain_set]}
            self._built[law_key] = build_settings(
                self.controller, self.scenarios[0], controller, self.plant_fixed, "run"
            )
        if plant_key not in self._built:
            plant = {**self.plant_fixed, **self.plant_draws[draw]}
            self._built[plant_key] = build_settings(
                self.controller, self.scenarios[scenario], self.fixed, plant, "run"
            )
        return dataclasses.replace(
            self._built[law_key], scenario=self.scenarios[scenario], plant=self._built[plant_key].plant
        )

    def columns(self) -> tuple[str, ...]:
        """Every ``scenario.index`` column of a gain set."""
        return tuple(f"{s.name}.{index}" for s in self.scenarios for index in INDEX_NAMES)


# ----------------------------------------------------------------------------- names and configs


def _controller_sections(controller: str) -> dict[str, tuple[type, Any]]:
    law = law_table()[controller].config
    return {
        controller: (law, law()),
        "td": (TrackingDifferentiatorConfig, TrackingDifferentiatorConfig()),
        "fleso": (FLESOConfig, FLESOConfig()),
        "model": (SMMParameters, SMMParameters()),
        "output": (OutputLimitConfig, OutputLimitConfig()),
    }


def _fields(config_cls: type, prefix: str) -> dict[str, Any]:
    return {f"{prefix}.{f.name}" if prefix else f.name: f for f in config_fields(config_cls)}


def _split(where: str, name: str) -> tuple[str, int | None]:
    match = _INDEXED.match(name) if isinstance(name, str) else None
    if match is None:
        raise SpecError(
            f"{where}: {name!r} is not a parameter name (e.g. fpdeso.fuzzy.kd0 or fpdeso.fuzzy.kd0[1])"
        )
    joint = match.group("joint")
    return match.group("name"), None if joint is None else int(joint)


def _check_name(where: str, name: str, known: Mapping[str, Any], hint: str) -> None:
    base, joint = _split(where, name)
    field = known.get(base)
    if field is None:
        raise SpecError(f"{where}: unknown parameter {name!r} ({hint}){did_you_mean(base, known)}")
    if joint is not None and field.length != 2:
        raise SpecError(f"{where}: {base!r} is not a per-joint parameter, so {name!r} has no joint index")


def _merged(where: str, values: Mapping[str, Any], current: Mapping[str, Any]) -> dict[str, Any]:
    """Flat values with ``name[j]`` entries folded into their pair (taken from ``current``).

    One number for a per-joint parameter is given to both joints.
    """
    result: dict[str, Any] = {}
    for name, value in values.items():
        base, joint = _split(where, name)
        if joint is None:
            per_joint = isinstance(current.get(base), list) and len(current[base]) == 2
            number = isinstance(value, (int, float)) and not isinstance(value, bool)
            result[base] = [value, value] if per_joint and number else value
            continue
        pair = list(result.get(base, current[base]))
        pair[joint] = value
        result[base] = pair
    return result


def _build(config_cls: type, default: Any, prefix: str, values: Mapping[str, Any], where: str) -> Any:
    current = config_to_parameters(default, prefix)
    merged = _merged(where, values, current)
    try:
        return config_from_parameters(config_cls, default, merged, prefix)
    except (TypeError, ValueError) as error:
        raise SpecError(f"{where}: {error}") from None


def build_settings(
    controller: str, scenario: Scenario, gains: Mapping[str, Any], plant: Mapping[str, Any], where: str
) -> RunSettings:
    """The run settings for controller parameters ``gains`` and plant parameters ``plant`` (node names).

    Raises:
        SpecError: A value is refused by its config dataclass (the message names ``where``).
    """
    built: dict[str, Any] = {}
    for prefix, (config_cls, default) in _controller_sections(controller).items():
        mine = {name: value for name, value in gains.items() if name.split(".")[0].split("[")[0] == prefix}
        built[prefix] = _build(config_cls, default, prefix, mine, where)
    base = scenario_plant_config(scenario)
    plant_default = PlantParameters(
        params=base.params,
        inertia_scale=base.inertia_scale,
        noise_std=base.noise_std,
        disturbance=base.disturbance,
    )
    plant_values = dict(plant)
    if any(isinstance(v, bool) for v in plant_values.values()):
        raise SpecError(f"{where}: plant parameters are numbers, strings or lists, got a bool")
    parameters = _build(PlantParameters, plant_default, "", plant_values, where)
    plant_config = dataclasses.replace(parameters.plant_config, control_period=base.control_period)
    try:
        return RunSettings(
            scenario=scenario,
            controller=controller,
            law=built[controller],
            plant=plant_config,
            td=built["td"],
            fleso=built["fleso"],
            model=built["model"],
            output=built["output"],
        )
    except ValueError as error:
        raise SpecError(f"{where}: {error}") from None


# ------------------------------------------------------------------------------------ parsing


def _mapping(where: str, value: object) -> Mapping[str, Any]:
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise SpecError(f"{where} must be a mapping, got {value!r}")
    return value


def _number(where: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise SpecError(f"{where} must be a finite number, got {value!r}")
    return float(value)


def _count(where: str, value: object, minimum: int = 1) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise SpecError(f"{where} must be an integer >= {minimum}, got {value!r}")
    return value


def _gain_values(spec: Mapping[str, Any], controller: str) -> tuple[tuple[str, ...], list[ParameterValues]]:
    gains = _mapping("gains", spec.get("gains"))
    known: dict[str, Any] = {}
    for prefix, (config_cls, _) in _controller_sections(controller).items():
        known.update(_fields(config_cls, prefix))
    hint = f"the sweep runs {controller}: names start with {controller}., td., fleso., model. or output"
    grids: dict[str, list[Any]] = {}
    ranges: dict[str, tuple[float, float, bool]] = {}
    for name, entry in gains.items():
        where = f"gains.{name}"
        _check_name(where, name, known, hint)
        entry = _mapping(where, entry)  # noqa: PLW2901 (the same entry, checked to be a mapping)
        if set(entry) - {"grid", "range", "log"} or ("grid" in entry) == ("range" in entry):
            raise SpecError(
                f"{where} needs exactly one of 'grid' (a list) or 'range' ([low, high]), got {dict(entry)!r}"
            )
        if "grid" in entry:
            values = entry["grid"]
            if not isinstance(values, list) or not values:
                raise SpecError(f"{where}.grid must be a non-empty list, got {values!r}")
            grids[name] = values
        else:
            bounds = entry["range"]
            if not isinstance(bounds, list) or len(bounds) != 2:
                raise SpecError(f"{where}.range must be [low, high], got {bounds!r}")
            low, high = (_number(f"{where}.range", value) for value in bounds)
            if not low < high:
                raise SpecError(f"{where}.range must have low < high, got {bounds!r}")
            log = bool(entry.get("log", False))
            if log and low <= 0.0:
                raise SpecError(f"{where}.range must be > 0 with log: true, got {bounds!r}")
            ranges[name] = (low, high, log)
    sampling = _mapping("sampling", spec.get("sampling"))
    draws: list[dict[str, Any]] = [{}]
    if ranges:
        method = sampling.get("method", "lhs")
        if method not in _SAMPLING:
            raise SpecError(f"sampling.method must be one of {_SAMPLING}, got {method!r}")
        count = _count("sampling.count", sampling.get("count"))
        seed = _count("sampling.seed", sampling.get("seed", 0), 0)
        if method == "lhs":
            unit = qmc.LatinHypercube(d=len(ranges), seed=np.random.default_rng(seed)).random(count)
        else:
            unit = np.random.default_rng(seed).random((count, len(ranges)))
        draws = []
        for row in unit:
            draw = {}
            for (name, (low, high, log)), u in zip(ranges.items(), row, strict=True):
                draw[name] = float(
                    math.exp(math.log(low) + u * (math.log(high) - math.log(low)))
                    if log
                    else low + u * (high - low)
                )
            draws.append(draw)
    elif sampling:
        raise SpecError("sampling is given but no gain has a 'range'")
    sets = [
        {**dict(zip(grids, combination, strict=True)), **draw}
        for combination in itertools.product(*grids.values())
        for draw in draws
    ]
    # Validate every grid value and both ends of every range by building the configs.
    for name, values in grids.items():
        for value in values:
            _validate_controller(controller, {name: value}, f"gains.{name}.grid value {value!r}")
    for name, (low, high, _) in ranges.items():
        for value in (low, high):
            _validate_controller(controller, {name: value}, f"gains.{name}.range end {value!r}")
    return (*grids, *ranges), sets


def _validate_controller(controller: str, values: Mapping[str, Any], where: str) -> None:
    build_settings(controller, get_scenario("step"), values, {}, where)


def _distribution(where: str, entry: object, rng: np.random.Generator, base: object, count: int) -> list[Any]:
    entry = _mapping(where, entry)
    kinds = [kind for kind in ("uniform", "normal", "integers", "choice") if kind in entry]
    if len(kinds) != 1 or set(entry) - {*kinds, "relative"}:
        raise SpecError(
            f"{where} needs one of uniform: [low, high], normal: [mean, std], integers: [low, high], "
            "choice: [...]"
        )
    kind = kinds[0]
    args = entry[kind]
    if not isinstance(args, list) or not args or (kind != "choice" and len(args) != 2):
        raise SpecError(
            f"{where}.{kind} must be a list of {'values' if kind == 'choice' else 'two numbers'}, "
            f"got {args!r}"
        )
    if kind == "uniform":
        low, high = (_number(f"{where}.uniform", v) for v in args)
        values: list[Any] = rng.uniform(low, high, count).tolist()
    elif kind == "normal":
        mean, std = (_number(f"{where}.normal", v) for v in args)
        values = rng.normal(mean, std, count).tolist()
    elif kind == "integers":
        low, high = (_count(f"{where}.integers", v, 0) for v in args)
        values = rng.integers(low, high, count, endpoint=True).tolist()
    else:
        values = [args[i] for i in rng.integers(0, len(args), count)]
    if entry.get("relative", False):
        if kind in ("integers", "choice"):
            raise SpecError(f"{where}: relative applies to uniform and normal draws only")
        if isinstance(base, (list, tuple)):
            return [[v * b for b in base] for v in values]
        return [v * float(base) for v in values]  # type: ignore[arg-type]
    return values


def _plant_values(
    spec: Mapping[str, Any], scenario: Scenario
) -> tuple[ParameterValues, list[ParameterValues]]:
    known = _fields(PlantParameters, "")
    known.pop("plant_config", None)
    hint = "plant parameters are smm_sim_node's: params.*, inertia_scale, noise_std, seed, disturbance, ..."
    fixed = dict(_mapping("plant", spec.get("plant")))
    for name in fixed:
        _check_plant_name(f"plant.{name}", name, known, hint)
    draws_spec = _mapping("plant_draws", spec.get("plant_draws"))
    parameters = _mapping("plant_draws.parameters", draws_spec.get("parameters"))
    if not parameters:
        if draws_spec and set(draws_spec) - {"count", "seed"}:
            raise SpecError(
                f"plant_draws has unknown keys {sorted(set(draws_spec) - {'count', 'seed', 'parameters'})}"
            )
        return fixed, [{}]
    count = _count("plant_draws.count", draws_spec.get("count"))
    rng = np.random.default_rng(_count("plant_draws.seed", draws_spec.get("seed", 0), 0))
    base_values = config_to_parameters(PlantParameters(params=scenario_plant_config(scenario).params))
    columns: dict[str, list[Any]] = {}
    for name, entry in parameters.items():
        where = f"plant_draws.parameters.{name}"
        _check_plant_name(where, name, known, hint)
        base_name, joint = _split(where, name)
        base = base_values[base_name] if joint is None else base_values[base_name][joint]
        if name in fixed:
            base = fixed[name]
        columns[name] = _distribution(where, entry, rng, base, count)
    draws = [{name: values[i] for name, values in columns.items()} for i in range(count)]
    return fixed, draws


def _check_plant_name(where: str, name: str, known: Mapping[str, Any], hint: str) -> None:
    base, _ = _split(where, name)
    if base in _PLANT_REFUSED:
        raise SpecError(f"{where}: {base} cannot be swept ({_PLANT_REFUSED[base]})")
    _check_name(where, name, known, hint)


def _column(where: str, name: object, scenarios: Sequence[Scenario]) -> str:
    if not isinstance(name, str):
        raise SpecError(f"{where} must be an index name, got {name!r}")
    scenario, _, index = name.rpartition(".")
    names = [s.name for s in scenarios]
    if not scenario:
        if len(scenarios) != 1:
            raise SpecError(f"{where}: {name!r} needs its scenario (one of {names}), e.g. {names[0]}.{name}")
        scenario = names[0]
    if scenario not in names:
        raise SpecError(f"{where}: scenario {scenario!r} of {name!r} is not swept ({names})")
    if index not in INDEX_NAMES:
        raise SpecError(f"{where}: unknown index {index!r}; indices: {', '.join(INDEX_NAMES)}")
    return f"{scenario}.{index}"


def _constraints(spec: Mapping[str, Any], scenarios: Sequence[Scenario]) -> tuple[Constraint, ...]:
    result = []
    for name, entry in _mapping("constraints", spec.get("constraints")).items():
        where = f"constraints.{name}"
        column = _column(where, name, scenarios)
        for op, bound in _mapping(where, entry).items():
            if op not in _OPERATORS:
                raise SpecError(f"{where}: unknown operator {op!r}; operators: {', '.join(_OPERATORS)}")
            if isinstance(bound, (int, float)) and not isinstance(bound, bool):
                result.append(Constraint(column, op, _number(f"{where}.{op}", bound)))
                continue
            laws = _mapping(f"{where}.{op}", bound) if isinstance(bound, Mapping) else {"controllers": bound}
            controllers = laws.get("controllers")
            controllers = [controllers] if isinstance(controllers, str) else controllers
            if (
                not isinstance(controllers, list)
                or not controllers
                or any(c not in law_table() for c in controllers)
            ):
                raise SpecError(
                    f"{where}.{op}: a bound is a number or laws among {law_names()}, got {bound!r}"
                )
            factor = _number(f"{where}.{op}.factor", laws.get("factor", 1.0))
            result.append(Constraint(column, op, None, tuple(controllers), factor))
    return tuple(result)


def _claims(scenarios: Sequence[Scenario]) -> tuple[Constraint, ...]:
    """The claims of ``smm_analysis.reproduction.acceptance`` as constraints on step, case1 and case2."""
    names = {s.name for s in scenarios}
    if not {"step", "case1", "case2"} <= names:
        raise SpecError(f"reproduction_claims needs the scenarios step, case1 and case2, got {sorted(names)}")
    low, high = STEP_RISE_TIME_RANGE
    result = []
    for joint in ("alpha", "beta"):
        result += [
            Constraint(f"step.overshoot_{joint}", "<", STEP_OVERSHOOT_LIMIT),
            Constraint(f"step.rise_time_{joint}", ">=", low),
            Constraint(f"step.rise_time_{joint}", "<=", high),
            Constraint(f"case1.RMS_{joint}", "<", None, PAPER_LAWS[1:]),
            Constraint(f"case1.Ma_{joint}", "<", None, PAPER_LAWS[1:]),
            Constraint(f"case2.RMS_{joint}", "<=", None, ("fpd",), 1.0 - CASE2_RMS_REDUCTION),
            Constraint(f"case2.eps_u_{joint}", "<", None, ("fpd",)),
        ]
    return tuple(result)


_KEYS = {
    "name",
    "scenarios",
    "controller",
    "duration",
    "fixed",
    "gains",
    "sampling",
    "plant",
    "plant_draws",
    "objectives",
    "statistic",
    "constraints",
    "reproduction_claims",
    "select",
    "batch_size",
}


def parse_spec(spec: Mapping[str, Any]) -> SweepSpec:
    """Validates a spec mapping (as loaded from YAML).

    Raises:
        SpecError: Naming the field that is wrong.
    """
    if not isinstance(spec, Mapping):
        raise SpecError(f"a sweep spec is a mapping, got {type(spec).__name__}")
    unknown = set(spec) - _KEYS
    if unknown:
        raise SpecError(f"unknown spec keys {sorted(unknown)}; known: {sorted(_KEYS)}")
    controller = spec.get("controller")
    if not isinstance(controller, str) or controller not in law_table():
        raise SpecError(f"controller must be one of {law_names()}, got {controller!r}")
    names = spec.get("scenarios")
    names = [names] if isinstance(names, str) else names
    if not isinstance(names, list) or not names:
        raise SpecError(f"scenarios must be a scenario name or a non-empty list, got {names!r}")
    try:
        scenarios = [get_scenario(name) for name in names]
    except UnknownScenarioError as error:
        raise SpecError(f"scenarios: {error}") from None
    if "duration" in spec:
        duration = _number("duration", spec["duration"])
        scenarios = [scenario.with_duration(duration) for scenario in scenarios]
    fixed = dict(_mapping("fixed", spec.get("fixed")))
    known: dict[str, Any] = {}
    for prefix, (config_cls, _) in _controller_sections(controller).items():
        known.update(_fields(config_cls, prefix))
    for name in fixed:
        _check_name(f"fixed.{name}", name, known, f"the sweep runs {controller}")
    _validate_controller(controller, fixed, "fixed")
    varied, gain_sets = _gain_values(spec, controller)
    for name in varied:
        if name in fixed:
            raise SpecError(f"gains.{name} is also in fixed")
    plant_fixed, draws = _plant_values(spec, scenarios[0])
    for index, draw in enumerate(draws[:1] + draws[-1:]):
        for scenario in scenarios:
            build_settings(controller, scenario, fixed, {**plant_fixed, **draw}, f"plant draw {index}")
    objectives_spec = spec.get("objectives")
    if not isinstance(objectives_spec, list) or not objectives_spec:
        raise SpecError(f"objectives must be a non-empty list of index names, got {objectives_spec!r}")
    objectives = tuple(_column(f"objectives[{i}]", name, scenarios) for i, name in enumerate(objectives_spec))
    statistic = spec.get("statistic", "p50")
    if statistic not in STATISTICS:
        raise SpecError(f"statistic must be one of {STATISTICS}, got {statistic!r}")
    select = _column("select", spec.get("select", objectives_spec[0]), scenarios)
    return SweepSpec(
        name=str(spec.get("name", "sweep")),
        controller=controller,
        scenarios=tuple(scenarios),
        gain_sets=tuple(gain_sets),
        varied=varied,
        fixed=fixed,
        plant_fixed=plant_fixed,
        plant_draws=tuple(draws),
        objectives=objectives,
        statistic=statistic,
        constraints=_constraints(spec, scenarios)
        + (_claims(scenarios) if spec.get("reproduction_claims") else ()),
        select=select,
        batch_size=_count("batch_size", spec.get("batch_size", 250)),
        source=dict(spec),
    )


def load_spec(path: Path) -> SweepSpec:
    """Reads and validates a spec file.

    Raises:
        SpecError: The file cannot be read or parsed, or the spec is invalid.
    """
    try:
        document = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, yaml.YAMLError) as error:
        raise SpecError(f"{path}: {error}") from None
    return parse_spec(document)
