"""smm_node_runtime.diagnostics: DiagnosticsPublisher with a real node, Health, CountWindows, level rules."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from ros_harness import spin_until
from smm_msgs_py.qos import diagnostic_qos
from smm_msgs_py.topics import DIAGNOSTICS

from smm_node_runtime import (
    CountWindows,
    DiagnosticsPublisher,
    Health,
    Level,
    level_for,
    make_executor,
    worst,
)

pytestmark = pytest.mark.ros


@dataclass
class Source:
    """A health whose level a test sets."""

    level: Level = Level.OK
    calls: int = 0
    values: dict[str, object] = field(default_factory=lambda: {"loop_rate_hz": 1000.0, "last_error": ""})

    def __call__(self) -> Health:
        self.calls += 1
        return Health(self.level, f"level {self.level.name}", self.values)


@pytest.fixture
def rig(ros_context: Any) -> Any:
    node = rclpy.create_node("diag_test", context=ros_context)
    probe = rclpy.create_node("diag_probe", context=ros_context)
    received: list[DiagnosticArray] = []
    probe.create_subscription(DiagnosticArray, DIAGNOSTICS, received.append, diagnostic_qos())
    executor = make_executor(ros_context)
    executor.add_node(node)
    executor.add_node(probe)
    yield node, executor, received
    executor.shutdown()
    node.destroy_node()
    probe.destroy_node()


def test_the_status_goes_out_every_period_named_after_the_node_with_its_values(rig: Any) -> None:
    node, executor, received = rig
    source = Source()
    publisher = DiagnosticsPublisher(node, source, period_s=0.05)
    assert spin_until(executor, lambda: len(received) >= 3, 10.0)
    status = received[-1].status[0]
    assert status.name == "/diag_test"
    assert status.level == bytes([Level.OK])
    assert status.hardware_id == "smm"
    assert status.message == "level OK"
    assert {kv.key: kv.value for kv in status.values} == {"loop_rate_hz": "1000.0", "last_error": ""}
    assert publisher.published >= 3
    publisher.destroy()


def test_a_level_change_is_sent_at_once_and_an_unchanged_level_is_not(rig: Any) -> None:
    node, executor, received = rig
    source = Source()
    publisher = DiagnosticsPublisher(node, source, period_s=3600.0)  # no periodic status during the test
    publisher.check()
    assert spin_until(executor, lambda: len(received) == 1, 10.0)
    publisher.check()  # same level: nothing
    source.level = Level.ERROR
    publisher.check()
    assert spin_until(executor, lambda: len(received) == 2, 10.0)
    spin_until(executor, lambda: False, 0.2)
    assert [array.status[0].level for array in received] == [bytes([Level.OK]), bytes([Level.ERROR])]
    assert publisher.level is Level.ERROR
    publisher.destroy()


def test_on_period_runs_before_each_periodic_status(rig: Any) -> None:
    node, executor, _ = rig
    order: list[str] = []
    source = Source()

    def collect() -> Health:
        order.append("collect")
        return source()

    publisher = DiagnosticsPublisher(node, collect, period_s=0.05, on_period=lambda: order.append("period"))
    assert spin_until(executor, lambda: order.count("collect") >= 2, 10.0)
    assert order[:4] == ["period", "collect", "period", "collect"]
    publisher.destroy()


def test_the_period_must_be_positive(ros_context: Any) -> None:
    node = rclpy.create_node("diag_bad", context=ros_context)
    with pytest.raises(ValueError, match="period"):
        DiagnosticsPublisher(node, Source(), period_s=0.0)
    node.destroy_node()


def test_count_windows_report_the_increase_over_the_last_complete_period() -> None:
    windows = CountWindows({})
    assert windows.rate("steps") == 0.0
    windows.roll({"steps": 10, "drops": 1})
    assert windows.last == {"steps": 10, "drops": 1}
    assert windows.since({"steps": 25, "drops": 1}) == {"steps": 15, "drops": 0}
    windows.roll({"steps": 25, "drops": 1})
    assert windows.last == {"steps": 15, "drops": 0}
    assert windows.rate("steps") > 0.0


def test_worst_finding_decides_the_level_and_comes_first() -> None:
    health = worst([(Level.WARN, "w"), (Level.ERROR, "e")], "fine", {})
    assert health.level is Level.ERROR and health.message == "e; w"
    assert worst([], "fine", {"a": 1}) == Health(Level.OK, "fine", {"a": 1})


@pytest.mark.parametrize(("value", "expected"), [(0.0, Level.OK), (1.0, Level.WARN), (5.0, Level.ERROR)])
def test_level_for_thresholds_are_inclusive(value: float, expected: Level) -> None:
    assert level_for(value, warn=1.0, error=5.0) is expected
