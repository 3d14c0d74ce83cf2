"""python-can's ``udp_multicast`` bus, opened only when its IPv4 group stays on loopback. No ROS.

Outside a private network namespace the group's frames leave by the default route, onto the LAN; in one,
``ip route add 224.0.0.0/4 dev lo`` keeps them on ``lo`` (tests/netns_exec.py adds it). docs/HW_CANOPEN.md.
"""

from __future__ import annotations

import re
import subprocess

import can

__all__ = ["MulticastRouteError", "check_loopback_route", "loopback_multicast_bus"]


class MulticastRouteError(RuntimeError):
    """The multicast group would leave this machine (its route is not over ``lo``)."""


def check_loopback_route(group: str) -> None:
    """Refuses unless the kernel routes IPv4 ``group`` over ``lo`` (``ip route get``).

    Raises:
        MulticastRouteError: Another device, or no route.
    """
    try:
        answer = subprocess.run(
            ["ip", "-4", "route", "get", group], capture_output=True, text=True, check=False, timeout=10
        )
    except (OSError, subprocess.TimeoutExpired) as error:
        raise MulticastRouteError(f"cannot ask the kernel's route to {group}: {error}") from error
    match = re.search(r"\bdev (\S+)", answer.stdout)
    if answer.returncode != 0 or match is None or match.group(1) != "lo":
        found = match.group(1) if match else (answer.stderr.strip() or "no route")
        raise MulticastRouteError(
            f"multicast group {group} goes over {found}, not lo: the emulated bus would leave this "
            f"machine; route it to loopback first (ip route add 224.0.0.0/4 dev lo, in a private netns)"
        )


def loopback_multicast_bus(group: str, port: int) -> can.BusABC:
    """A ``udp_multicast`` bus on IPv4 ``group`` and ``port``, refused unless the group routes over ``lo``.

    Raises:
        MulticastRouteError: The group's route is not over ``lo``.
    """
    check_loopback_route(group)
    return can.Bus(interface="udp_multicast", channel=group, port=port, receive_own_messages=False)
