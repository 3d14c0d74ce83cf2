"""What each step writes: its Markdown section with figures and the bridge parameters it found."""

from __future__ import annotations

import math
from collections.abc import Sequence

from smm_analysis.identification import PARAMETER_NAMES
from smm_hw_bridge.bridge_config import BridgeConfig
from smm_hw_bridge.encoder import EncoderConfig

from smm_commissioning.identify import LOOP_BLEND, OPEN_MARGIN, IdentifyResult
from smm_commissioning.jog import JogConfig, JointJog
from smm_commissioning.probe import JOINTS, ProbeConfig, ProbeResult, zero_offset
from smm_commissioning.tune import TuneConfig, TuneResult
from smm_commissioning.verify import Verdict, VerifyConfig

__all__ = [
    "BRIDGE_NODE",
    "bridge_parameters",
    "identify_markdown",
    "jog_markdown",
    "probe_markdown",
    "tune_markdown",
    "verify_markdown",
]

BRIDGE_NODE = "/**/hw_bridge_node"
"""Parameter-file key of the bridge (what ``smm-launch --params-file`` passes on)."""
DEADBAND_BLEND = 5.0
"""``bridge.valve.deadband_blend`` with an overlap: short spells inside it (docs/BENCH.md, "The valve")."""


def probe_markdown(result: ProbeResult, config: ProbeConfig) -> str:
    """The probe's section: what it read, what it checked, what is wrong."""
    verdict = "passed" if result.passed else "FAILED"
    canopen = result.link == "canopen"
    supply = "supply (bar, stated: canopen.supply_bar)" if canopen else "supply (bar)"
    stuck = "0x6381:01 below" if canopen else f"> {config.stuck_spread:g} when the supply's is"
    lines = [
        f"## probe: {verdict}",
        "",
        f"Output disabled for {result.ticks} feedbacks (enabled commands sent: "
        f"{'SOME' if result.enabled else 'none'}); "
        f"pose confirmed by the operator: alpha {result.pose[0]:g} rad, beta {result.pose[1]:g} rad.",
        "",
        "| reading | alpha | beta | check |",
        "|---|---|---|---|",
        f"| {supply} | {result.supply_bar:.2f} | | >= {config.supply_min:g} |",
        f"| counts at the pose | {result.counts_at_pose[0]} | {result.counts_at_pose[1]} | |",
        f"| count span at rest (counts) | {result.counts_span[0]} | {result.counts_span[1]} | "
        f"<= {config.rest_motion_max:g} rad |",
        f"| count noise (std, counts) | {result.counts_std[0]:.2f} | {result.counts_std[1]:.2f} | |",
        f"| load torque at rest (N m) | {result.rest_torque[0]:+.3f} | {result.rest_torque[1]:+.3f} | "
        f"abs <= {config.rest_torque_max:g} |",
        f"| load channel noise (std, codes) | {result.load_std[0]:.2f} | {result.load_std[1]:.2f} | "
        f"{stuck} |",
        f"| faults / status bits | {result.faults:#06x} | {result.status:#06x} | faults 0 |",
        "",
    ]
    if result.nodes:
        lines += [
            "| CANopen node | device type 0x1000 | NMT state | device state | pressure actual 0x6381:01 "
            "mean / std / span (units) |",
            "|---|---|---|---|---|",
        ]
        for node in result.nodes:
            pressure = ""
            if node.pressure is not None:
                mean, spread, span = node.pressure
                pressure = f"{mean:.1f} / {spread:.2f} / {span}"
            lines.append(
                f"| {node.name} | 0x{node.device_type:08X} (CiA {node.device_type & 0xFFFF}) | {node.nmt} | "
                f"{node.state or '-'} | {pressure} |"
            )
        lines.append("")
    if result.findings:
        lines += ["What is wrong:", ""] + [f"- {finding}" for finding in result.findings] + [""]
    if result.notes:
        lines += ["Not checked:", ""] + [f"- {note}" for note in result.notes] + [""]
    return "\n".join(lines) + "\n"


def jog_markdown(results: tuple[JointJog, ...], config: JogConfig, why: str = "") -> str:
    """The jog's section: each joint's truths with the pulses behind them."""
    lines = [
        f"## jog: {'FAILED' if why else 'passed'}",
        "",
        f"Open-loop pulses of {config.pulse_ticks} ticks inside +-{config.window:g} rad of the start, speed "
        f"limit {config.velocity_limit:g} rad/s, valves disabled between pulses ({config.rest_ticks} ticks).",
        "",
    ]
    if why:
        lines += [f"Stopped: {why}. The valves are disabled.", ""]
    if results:
        lines += [
            "| joint | encoder direction | valve polarity | null bias (codes) | deadband (codes) | "
            "gain + (codes/N m) | gain - (codes/N m) | lag (ms) | largest excursion (rad) | pulses |",
            "|---|---|---|---|---|---|---|---|---|---|",
        ]
        for r in results:
            cut = sum(1 for p in r.pulses if p.cut)
            lines.append(
                f"| {JOINTS[r.joint]} | {r.direction:+d} | {r.polarity:+d} | {r.null_bias:.0f} | "
                f"{r.deadband:.0f} | "
                f"{r.gain_positive:.1f} | {r.gain_negative:.1f} | {r.lag * 1e3:.1f} | {r.excursion:.3f} | "
                f"{len(r.pulses)} ({cut} cut at a limit) |"
            )
        lines.append("")
        for r in results:
            lines += [f"Pulses of {JOINTS[r.joint]} (code: settled torque, N m):", ""]
            shown = [
                f"{p.code:+d}: {p.torque:+.3f}" if math.isfinite(p.torque) else f"{p.code:+d}: cut ({p.cut})"
                for p in r.pulses
            ]
            lines += [", ".join(shown), ""]
    return "\n".join(lines) + "\n"


def bridge_parameters(
    results: tuple[JointJog, ...],
    probe_counts: tuple[int, int],
    pose: tuple[float, float],
    encoder: EncoderConfig,
) -> dict[str, object]:
    """``bridge.valve.*`` and ``bridge.encoder.*`` from the jog (both joints), the zero from the probe."""
    by_joint = {r.joint: r for r in results}
    if sorted(by_joint) != [0, 1]:
        raise ValueError("the bridge's parameters need both joints jogged")
    ordered = (by_joint[0], by_joint[1])
    zero = [zero_offset(probe_counts[j], pose[j], ordered[j].direction, encoder, j) for j in range(2)]
    deadband = [round(r.deadband, 1) for r in ordered]
    return {
        "bridge.encoder.direction": [r.direction for r in ordered],
        "bridge.encoder.zero_offset": zero,
        "bridge.valve.polarity": [r.polarity for r in ordered],
        "bridge.valve.null_bias": [round(r.null_bias, 1) for r in ordered],
        "bridge.valve.deadband": deadband,
        "bridge.valve.gain": [round(r.gain_positive, 3) for r in ordered],
        "bridge.valve.gain_negative": [round(r.gain_negative, 3) for r in ordered],
        "bridge.valve.deadband_blend": DEADBAND_BLEND if any(deadband) else 50.0,
    }


def identify_markdown(
    result: IdentifyResult, jog: BridgeConfig, refined: dict[str, list[float] | float]
) -> str:
    """The identify section: the model with its intervals, the valve's gain, the overlap's edges."""
    ident = result.identification
    lines = [
        "## identify: passed",
        "",
        f"The excitation closed through the bridge on jog's parameters ({len(result.record.t_ns)} ticks, "
        f"largest |q| {max(result.record.peak):.3f} rad), its bag fitted as `smm-bag identify` does with the "
        f"measured torque: {ident.rows} joint rows, condition number {ident.condition_number:.3g}, torque "
        f"NRMSE {ident.fits[0].nrmse[0]:.4f} (alpha) {ident.fits[0].nrmse[1]:.4f} (beta); intervals: block "
        f"bootstrap, {ident.settings.bootstrap} replicates (identify_identification.md has the full report).",
        "",
        "| parameter | estimate | 95 % interval |",
        "|---|---|---|",
    ]
    for index, name in enumerate(PARAMETER_NAMES):
        low, high = ident.interval[index]
        lines.append(f"| {name} | {ident.theta[index]:.6g} | [{low:.6g}, {high:.6g}] |")
    lines += [
        "",
        "Valve gain, measured over modelled torque (a check, not applied: the bridge's lag model parts from "
        "the valve's where the torque changes fast, jog's settled pulses give the gains; docs):",
        "",
        "| joint | positive torque | negative torque |",
        "|---|---|---|",
    ]
    gain = result.gain
    for j, name in enumerate(JOINTS):
        cells = [
            f"{gain.ratio[j, d]:.4f} [{gain.interval[j, d, 0]:.4f}, {gain.interval[j, d, 1]:.4f}]"
            for d in range(2)
        ]
        lines.append(f"| {name} | {cells[0]} | {cells[1]} |")
    lines += [
        "",
        "Edges of the overlap: between the last code that left the joint held by the oil and the first that "
        "moved it (codes held 0.35 s each); the check: where the line through the torques of the codes that "
        "moved it (M dq'/dt + F + G of the identified model, after the valve's lag) crosses zero:",
        "",
        "| joint | edge | jog's (codes) | found (codes) | the line's (codes) | torque per code (mN m) | "
        "line residual (mN m) | codes held |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for edge in result.edges:
        lines.append(
            f"| {JOINTS[edge.joint]} | {'high' if edge.side > 0 else 'low'} | {edge.start:.1f} | "
            f"{edge.edge:.1f} | {edge.line:.1f} | {edge.slope * 1e3:+.4f} | {edge.residual * 1e3:.3f} | "
            f"{len(edge.codes)} |"
        )
    lines += [
        "",
        "The valves' parameters, jog's and identify's (identify's deadband: the edges' half distance plus "
        f"{OPEN_MARGIN:g} codes, blend {LOOP_BLEND:g} codes: the code jumps over the overlap; docs):",
        "",
        "| parameter | jog | identify |",
        "|---|---|---|",
    ]
    valve = jog.valve
    before: dict[str, list[float] | float] = {
        "bridge.valve.null_bias": list(valve.null_bias),
        "bridge.valve.deadband": list(valve.deadband),
        "bridge.valve.deadband_blend": valve.deadband_blend,
    }
    for name, values in refined.items():
        lines.append(f"| {name} | {_pair(before[name])} | {_pair(values)} |")
    if result.warnings:
        lines += ["", "Left out by the identification:", "", *(f"- {w}" for w in result.warnings)]
    return "\n".join(lines) + "\n"


def tune_markdown(result: TuneResult, config: TuneConfig) -> str:
    """The tune section: the sweep and the chosen gains against the paper's."""
    spec = result.spec
    chosen, paper = result.chosen, result.paper
    gains = spec.gain_sets[chosen]
    lines = [
        "## tune: passed",
        "",
        f"`smm-sweep` on the identified model: {len(spec.gain_sets)} gain sets (k_p0 and k_d0 of FPDESO "
        "times "
        f"{', '.join(f'{f:g}' for f in config.factors)}) x {len(spec.plant_draws)} plants drawn within the "
        f"identified intervals, case 1 for {config.duration:g} s (tune/ holds the sweep: Parquet, plots, "
        "report.md, chosen.yaml). Chosen: no worse than the paper's gains on either joint in the worst "
        "draw, the least alpha RMS.",
        "",
        "| gain set | k_p0 | k_d0 | worst RMS alpha (mrad) | worst RMS beta (mrad) |",
        "|---|---|---|---|---|",
    ]
    for label, index in (("paper", paper), ("chosen", chosen)):
        values = spec.gain_sets[index]
        worst = result.worst(index)
        lines.append(
            f"| {label} ({index}) | {_pair(values['fpdeso.fuzzy.kp0'])} | "
            f"{_pair(values['fpdeso.fuzzy.kd0'])} | "
            f"{worst[0] * 1e3:.3f} | {worst[1] * 1e3:.3f} |"
        )
    lines += [
        "",
        f"Chosen gains: k_p0 {_pair(gains['fpdeso.fuzzy.kp0'])}, k_d0 {_pair(gains['fpdeso.fuzzy.kd0'])}.",
    ]
    return "\n".join(lines) + "\n"


def verify_markdown(verdict: Verdict, config: VerifyConfig) -> str:
    """The verify section: the bench's case 1 against the model's, and whether the bench is ready."""
    ratio = verdict.ratio
    lines = [
        f"## verify: {'READY' if verdict.ready else 'NOT READY'}",
        "",
        f"Case 1 for {config.duration:g} s closed on the commissioned parameters (the bridge's valve and "
        "encoder, the identified model, the chosen gains), against the same run on the identified model "
        f"(offline loop); RMS after {config.settled:g} s (the valves saturate before).",
        "",
        "| joint | bench RMS (mrad) | model's (mrad) | ratio | largest |q| (rad) |",
        "|---|---|---|---|---|",
    ]
    for j, name in enumerate(JOINTS):
        lines.append(
            f"| {name} | {verdict.bench[j] * 1e3:.3f} | {verdict.predicted[j] * 1e3:.3f} | {ratio[j]:.3f} | "
            f"{verdict.peak[j]:.3f} |"
        )
    lines.append("")
    if verdict.ready:
        lines.append(
            f"Ready: both joints within {config.ready_factor:g}x of the model. `commissioned.yaml` holds "
            "every parameter: `smm-launch --plant hardware --params-file DIR/commissioned.yaml` with the "
            "link's options (`--board ADDRESS:PORT`; CANopen: `--link canopen --board external`)."
        )
    else:
        lines.append(
            f"Not ready: a joint tracks worse than {config.ready_factor:g}x the model's prediction; "
            "no commissioned.yaml. Check the bench (friction, a sticking valve), then run jog again."
        )
    return "\n".join(lines) + "\n"


def _pair(values: Sequence[float] | float) -> str:
    items = list(values) if isinstance(values, Sequence) else [values]
    return ", ".join(f"{float(v):.6g}" for v in items)
