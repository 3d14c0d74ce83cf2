"""Bring up loopback in a fresh network namespace, then exec the given command.

Run as ``unshare --net -- python netns_exec.py CMD...``: the new namespace has only ``lo``, and it is down
until this script sets IFF_UP on it (ioctl, so no ``ip`` binary is needed). Nothing started afterwards can
reach any interface but loopback, which is what keeps DDS discovery of the test suite on this machine.
"""

from __future__ import annotations

import fcntl
import os
import socket
import struct
import subprocess
import sys

_SIOCGIFFLAGS = 0x8913
_SIOCSIFFLAGS = 0x8914
_IFF_UP = 0x1
_IFREQ = "16sH14x"


def bring_loopback_up() -> None:
    """Set the UP flag on ``lo`` in the current network namespace."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        request = struct.pack(_IFREQ, b"lo", 0)
        flags = struct.unpack(_IFREQ, fcntl.ioctl(sock.fileno(), _SIOCGIFFLAGS, request))[1]
        fcntl.ioctl(sock.fileno(), _SIOCSIFFLAGS, struct.pack(_IFREQ, b"lo", flags | _IFF_UP))


def route_multicast_to_loopback() -> None:
    """Routes IPv4 multicast over ``lo`` (the emulated CAN bus's udp_multicast); says why if it cannot."""
    try:
        done = subprocess.run(
            ["ip", "route", "add", "224.0.0.0/4", "dev", "lo"], capture_output=True, check=False
        )
    except OSError as error:
        print(f"netns_exec: no multicast route over lo: {error}", file=sys.stderr)
        return
    if done.returncode != 0:
        print(f"netns_exec: no multicast route over lo: {done.stderr.decode().strip()}", file=sys.stderr)


def interface_names() -> list[str]:
    """Names of the network interfaces visible in this namespace."""
    return [name for _, name in socket.if_nameindex()]


def main(argv: list[str]) -> int:
    """Bring ``lo`` up and replace this process by ``argv``."""
    if not argv:
        print("usage: netns_exec.py CMD [ARGS...]", file=sys.stderr)
        return 2
    bring_loopback_up()
    route_multicast_to_loopback()
    os.execvp(argv[0], argv)
    return 127  # not reached: execvp raises on failure


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
