"""What each step writes: its Markdown section with figures and the bridge parameters it found."""

from __future__ import annotations

import math

from smm_hw_bridge.encoder import EncoderConfig

from smm_commissioning.jog import JogConfig, JointJog
from smm_commissioning.probe import JOINTS, ProbeConfig, ProbeResult, zero_offset

__all__ = ["BRIDGE_NODE", "bridge_parameters", "jog_markdown", "probe_markdown"]

BRIDGE_NODE = "/**/hw_bridge_node"
"""Parameter-file key of the bridge (what ``smm-launch --params-file`` passes on)."""
DEADBAND_BLEND = 5.0
"""``bridge.valve.deadband_blend`` with an overlap: short spells inside it (docs/BENCH.md, "The valve")."""


def probe_markdown(result: ProbeResult, config: ProbeConfig) -> str:
    """The probe's section: what it read, what it checked, what is wrong."""
    verdict = "passed" if result.passed else "FAILED"
    lines = [
        f"## probe: {verdict}",
        "",
        f"Output disabled for {result.ticks} feedbacks (enabled commands sent: "
        f"{'SOME' if result.enabled else 'none'}); "
        f"pose confirmed by the operator: alpha {result.pose[0]:g} rad, beta {result.pose[1]:g} rad.",
        "",
        "| reading | alpha | beta | check |",
        "|---|---|---|---|",
        f"| supply (bar) | {result.supply_bar:.2f} | | >= {config.supply_min:g} |",
        f"| counts at the pose | {result.counts_at_pose[0]} | {result.counts_at_pose[1]} | |",
        f"| count span at rest (counts) | {result.counts_span[0]} | {result.counts_span[1]} | "
        f"<= {config.rest_motion_max:g} rad |",
        f"| count noise (std, counts) | {result.counts_std[0]:.2f} | {result.counts_std[1]:.2f} | |",
        f"| load torque at rest (N m) | {result.rest_torque[0]:+.3f} | {result.rest_torque[1]:+.3f} | "
        f"abs <= {config.rest_torque_max:g} |",
        f"| load channel noise (std, codes) | {result.load_std[0]:.2f} | {result.load_std[1]:.2f} | "
        f"> {config.stuck_spread:g} when the supply's is |",
        f"| faults / status bits | {result.faults:#06x} | {result.status:#06x} | faults 0 |",
        "",
    ]
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
