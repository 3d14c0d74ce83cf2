"""smm_node_runtime and smm_node_runtime.parameters with real ROS: executors, main, parameter binding."""

from __future__ import annotations

import signal
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest
import rclpy
from rcl_interfaces.msg import ParameterType
from rclpy.parameter import Parameter
from rclpy.task import Future
from ros_harness import spin_until
from smm_node_runtime.parameters import ConfigParameters
from smm_schema.ranges import above, bounds, check_bounds

from smm_node_runtime import SPIN_POLL_S, as_parameter_list, make_executor

pytestmark = pytest.mark.ros


@dataclass(frozen=True)
class Gains:
    """Test gains.

    Attributes:
        k: Per-joint gain (1/s), > 0.
        limit: A scalar limit (N m), > 0.
        mode: "a" or "b".
    """

    k: tuple[float, float] = field(default=(1.0, 2.0), metadata=above(0.0))
    limit: float = field(default=5.0, metadata=bounds(0.0, 100.0, low_open=True))
    mode: str = "a"

    def __post_init__(self) -> None:
        check_bounds(self)
        if self.mode not in ("a", "b"):
            raise ValueError(f"mode must be 'a' or 'b', got {self.mode!r}")


@pytest.fixture
def node(ros_context: Any) -> Any:
    created = rclpy.create_node("binding_test", context=ros_context)
    yield created
    created.destroy_node()


def test_parameters_are_declared_with_types_and_docstring_descriptions(node: Any) -> None:
    binding = ConfigParameters(node, "gains", Gains())
    assert binding.parameter_names == {"gains.k", "gains.limit", "gains.mode"}
    k, limit, mode = node.describe_parameters(["gains.k", "gains.limit", "gains.mode"])
    assert k.type == ParameterType.PARAMETER_DOUBLE_ARRAY
    assert k.description == "Per-joint gain (1/s), > 0."
    assert k.additional_constraints == "2 values, per joint (alpha, beta), each > 0"
    assert not k.floating_point_range  # ROS ranges are for scalars: the config checks the elements
    assert limit.type == ParameterType.PARAMETER_DOUBLE
    assert (limit.floating_point_range[0].from_value, limit.floating_point_range[0].to_value) == (0.0, 100.0)
    assert limit.additional_constraints == "in (0, 100]"  # the open end ROS cannot state
    assert mode.type == ParameterType.PARAMETER_STRING
    assert list(node.get_parameter("gains.k").value) == [1.0, 2.0]


def test_overrides_set_the_initial_config(ros_context: Any) -> None:
    overrides = as_parameter_list({"gains.k": (3.0, 4.0), "gains.mode": "b"})
    created = rclpy.create_node("overridden", context=ros_context, parameter_overrides=overrides)
    try:
        assert ConfigParameters(created, "gains", Gains()).config == Gains(k=(3.0, 4.0), mode="b")
    finally:
        created.destroy_node()


def test_invalid_initial_values_refuse_to_build(ros_context: Any) -> None:
    created = rclpy.create_node(
        "bad_start", context=ros_context, parameter_overrides=as_parameter_list({"gains.k": [-1.0, 1.0]})
    )
    try:
        with pytest.raises(ValueError, match="k must be > 0"):
            ConfigParameters(created, "gains", Gains())
    finally:
        created.destroy_node()


@pytest.mark.parametrize(
    ("name", "value", "reason"),
    [
        ("gains.k", [-1.0, 2.0], "k must be > 0 for both joints, got (-1.0, 2.0)"),
        ("gains.k", [1.0, 2.0, 3.0], "gains.k must have 2 values (alpha, beta), got 3: [1.0, 2.0, 3.0]"),
        ("gains.mode", "c", "mode must be 'a' or 'b', got 'c'"),
        ("gains.limit", 500.0, "out of range"),  # the ROS range of the scalar
        ("gains.limit", 0.0, "limit must be in (0, 100], got 0.0"),  # its open end: the config's check
        ("gains.limit", "x", "Wrong parameter type"),  # ROS's own type check
    ],
)
def test_rejected_changes_report_the_reason_and_keep_the_config(
    node: Any, name: str, value: Any, reason: str
) -> None:
    changes: list[Gains] = []
    binding = ConfigParameters(node, "gains", Gains(), on_change=changes.append)
    (result,) = node.set_parameters([Parameter(name, value=value)])
    assert not result.successful
    assert reason in result.reason
    assert binding.config == Gains()
    assert changes == []


def test_accepted_change_swaps_the_whole_config_once(node: Any) -> None:
    changes: list[Gains] = []
    binding = ConfigParameters(node, "gains", Gains(), on_change=changes.append)
    before = binding.config
    result = node.set_parameters_atomically(
        [Parameter("gains.k", value=[3.0, 4.0]), Parameter("gains.limit", value=7.0)]
    )
    assert result.successful
    assert binding.config == Gains(k=(3.0, 4.0), limit=7.0)
    assert changes == [binding.config]
    assert before == Gains()  # the old instance is untouched


def test_an_accepted_change_logs_each_changed_value_once_and_a_refused_one_nothing(
    node: Any, capfd: pytest.CaptureFixture[str]
) -> None:
    ConfigParameters(node, "gains", Gains())
    capfd.readouterr()
    assert node.set_parameters_atomically(
        [Parameter("gains.k", value=[3.0, 4.0]), Parameter("gains.limit", value=5.0)]  # limit unchanged
    ).successful
    assert not node.set_parameters([Parameter("gains.mode", value="c")])[0].successful
    lines = [line for line in "".join(capfd.readouterr()).splitlines() if "parameter gains." in line]
    assert len(lines) == 1, lines
    assert lines[0].endswith("[binding_test]: parameter gains.k: [1.0, 2.0] -> [3.0, 4.0]")


def test_extra_check_rejects_with_its_message(node: Any) -> None:
    def check(gains: Gains) -> None:
        if gains.limit > 10.0:
            raise ValueError(f"limit {gains.limit} exceeds the actuator's 10 N m")

    binding = ConfigParameters(node, "", Gains(), check=check)
    (result,) = node.set_parameters([Parameter("limit", value=11.0)])
    assert not result.successful and result.reason == "limit 11.0 exceeds the actuator's 10 N m"
    (result,) = node.set_parameters([Parameter("limit", value=9.0)])
    assert result.successful and binding.config.limit == 9.0


def test_read_only_parameters_refuse_changes(node: Any) -> None:
    ConfigParameters(node, "fixed", Gains(), read_only=True)
    (result,) = node.set_parameters([Parameter("fixed.limit", value=1.0)])
    assert not result.successful and "read-only" in result.reason


def test_bindings_ignore_parameters_of_other_prefixes(node: Any) -> None:
    first = ConfigParameters(node, "first", Gains())
    second = ConfigParameters(node, "second", Gains())
    (result,) = node.set_parameters([Parameter("second.limit", value=2.0)])
    assert result.successful
    assert first.config == Gains() and second.config.limit == 2.0


def test_executor_waits_are_bounded_even_without_timeout(ros_context: Any) -> None:
    created = rclpy.create_node("waits", context=ros_context)
    executor = make_executor(ros_context)
    executor.add_node(created)
    future = Future()
    ticks: list[int] = []

    def tick() -> None:
        ticks.append(1)
        if len(ticks) == 3:
            future.set_result(True)

    created.create_timer(0.05, tick)
    try:
        started = time.monotonic()
        executor.spin_once()  # must come back (EventsExecutor alone would block for ever)
        assert time.monotonic() - started < 10 * SPIN_POLL_S
        executor.spin_until_future_complete(future)
        assert future.done() and len(ticks) >= 3
    finally:
        executor.shutdown()
        created.destroy_node()


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_node_main_exits_cleanly_on_signal(ros_processes: Any, ros_context: Any, signum: int) -> None:
    # ament_python installs console scripts to <prefix>/lib/<package>/ (setup.cfg).
    executable = Path(sys.prefix) / "lib" / "smm_controller" / "td_node"
    assert executable.is_file(), f"{executable} is not installed (make setup)"
    process = ros_processes.start("td_node", [str(executable), "--ros-args", "-r", "__ns:=/smm"])
    probe = rclpy.create_node("watcher", context=ros_context)
    executor = make_executor(ros_context)
    executor.add_node(probe)
    try:
        seen = spin_until(
            executor, lambda: ("td_node", "/smm") in probe.get_node_names_and_namespaces(), 30.0
        )
        assert seen, process.logs()
        process.popen.send_signal(signum)
        code = process.popen.wait(timeout=15)
    finally:
        executor.shutdown()
        probe.destroy_node()
    logs = process.logs()
    assert code == 0, logs
    assert "Traceback" not in logs


@pytest.mark.parametrize(
    ("override", "message"),
    [
        ("td.speed:=[-1.0, 1.0]", "speed must be > 0 for both joints"),
        ("td.speed:=[1, 2]", "td.speed"),  # an integer array for a double-array parameter (rclpy's check)
    ],
)
def test_node_main_refuses_invalid_parameters_with_status_2(
    ros_processes: Any, override: str, message: str
) -> None:
    executable = Path(sys.prefix) / "lib" / "smm_controller" / "td_node"
    process = ros_processes.start("td_node", [str(executable), "--ros-args", "-p", override])
    code = process.popen.wait(timeout=30)
    logs = process.logs()
    assert code == 2, logs
    assert "invalid parameter" in logs and message in logs
    assert "Traceback" not in logs


def test_diagnostics_are_built_only_while_someone_listens(ros_context: Any) -> None:
    from std_msgs.msg import Float64MultiArray

    from smm_node_runtime import MeasurementDrivenNode

    node = MeasurementDrivenNode(node_name="lazy_diagnostics", context=ros_context)
    output_pub = node.create_publisher(Float64MultiArray, "lazy_out", 10)
    diagnostics_pub = node.create_publisher(Float64MultiArray, "lazy_diag", 10)
    builds: list[int] = []

    def outputs() -> list[Any]:
        return [(output_pub, Float64MultiArray())]

    def diagnostics() -> list[Any]:
        builds.append(1)
        return [(diagnostics_pub, Float64MultiArray())]

    try:
        assert node.answer(1, outputs, diagnostics)  # the first build learns the diagnostic topics
        assert node.answer(2, outputs, diagnostics)  # nobody listens: not built
        assert len(builds) == 1
        listener = rclpy.create_node("lazy_listener", context=ros_context)
        received: list[Any] = []
        listener.create_subscription(Float64MultiArray, "lazy_diag", received.append, 10)
        executor = rclpy.executors.SingleThreadedExecutor(context=ros_context)
        executor.add_node(listener)
        assert spin_until(executor, lambda: diagnostics_pub.get_subscription_count() > 0, timeout_s=10)
        assert node.answer(3, outputs, diagnostics)
        assert len(builds) == 2
        assert spin_until(executor, lambda: len(received) == 1, timeout_s=10)
        executor.shutdown()
        listener.destroy_node()
    finally:
        node.destroy_node()


def test_wait_for_delivery_returns_once_every_reader_has_it_and_the_writer_may_go(ros_context: Any) -> None:
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    from std_msgs.msg import UInt32

    from smm_node_runtime import wait_for_delivery

    qos = QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=1000,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.VOLATILE,
    )
    writer = rclpy.create_node("delivery_writer", context=ros_context)
    reader = rclpy.create_node("delivery_reader", context=ros_context)
    received: list[int] = []
    reader.create_subscription(UInt32, "delivery", lambda msg: received.append(msg.data), qos)
    publisher = writer.create_publisher(UInt32, "delivery", qos)
    executor = make_executor(ros_context)
    executor.add_node(reader)
    try:
        assert spin_until(executor, lambda: publisher.get_subscription_count() == 1, timeout_s=10.0)
        for k in range(500):
            publisher.publish(UInt32(data=k))
        assert wait_for_delivery(writer, 10.0) == []
        writer.destroy_node()  # what an exiting process does right after
        assert spin_until(executor, lambda: len(received) == 500, timeout_s=10.0)
        assert received == list(range(500))
    finally:
        executor.shutdown()
        reader.destroy_node()
