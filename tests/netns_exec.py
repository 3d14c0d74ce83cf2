"""Bring up loopback in a fresh network namespace, then exec the given command.

Run as ``unshare --net -- python netns_exec.py CMD...``: the new namespace has only ``lo``, and it is down
until this script sets IFF_UP on it (ioctl, so no ``ip`` binary is needed). Nothing started afterwards can
reach any interface but loopback, which is what keeps DDS discovery of the test suite on this machine.
A pytest-xdist worker enters a namespace of its own in-process instead (``enter_private_netns``).
"""

from __future__ import annotations

import ctypes
import fcntl
import os
import socket
import struct
import subprocess
import sys
import threading

_SIOCGIFFLAGS = 0x8913
_SIOCSIFFLAGS = 0x8914
_IFF_UP = 0x1
_IFREQ = "16sH14x"
_CLONE_NEWNET = 0x40000000


def bring_loopback_up() -> None:
    """Set the UP flag on ``lo`` in the current network namespace."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        request = struct.pack(_IFREQ, b"lo", 0)
        flags = struct.unpack(_IFREQ, fcntl.ioctl(sock.fileno(), _SIOCGIFFLAGS, request))[1]
        fcntl.ioctl(sock.fileno(), _SIOCSIFFLAGS, struct.pack(_IFREQ, b"lo", flags | _IFF_UP))


def route_multicast_to_loopback() -> str | None:
    """Routes IPv4 multicast over ``lo`` (the emulated CAN bus's udp_multicast); why not, if it cannot."""
    try:
        done = subprocess.run(
            ["ip", "route", "add", "224.0.0.0/4", "dev", "lo"], capture_output=True, check=False
        )
    except OSError as error:
        return f"no multicast route over lo: {error} (the 'ip' command, iproute2)"
    if done.returncode != 0:
        return f"no multicast route over lo: {done.stderr.decode().strip() or done.returncode}"
    return None


def netns_inode(pid: int | str = "thread-self") -> int:
    """The inode of the network namespace of ``pid`` (default: the calling thread)."""
    return os.stat(f"/proc/{pid}/ns/net").st_ino


def enter_private_netns() -> None:
    """Moves the calling (main) thread, and what it starts from then on, into a new network namespace with
    only ``lo``, up, and multicast routed over it.

    Raises:
        RuntimeError: Not the main thread, or a step failed (the reason given).
    """
    if threading.current_thread() is not threading.main_thread():
        raise RuntimeError("a private network namespace is entered from the main thread only")
    libc = ctypes.CDLL(None, use_errno=True)
    if libc.unshare(_CLONE_NEWNET) != 0:
        error = ctypes.get_errno()
        raise RuntimeError(f"unshare(CLONE_NEWNET) failed: {os.strerror(error)} (run as root)")
    bring_loopback_up()
    problem = route_multicast_to_loopback()
    if problem is not None:
        raise RuntimeError(problem)


def interface_names() -> list[str]:
    """Names of the network interfaces visible in this namespace."""
    return [name for _, name in socket.if_nameindex()]


def main(argv: list[str]) -> int:
    """Bring ``lo`` up and replace this process by ``argv``."""
    if not argv:
        print("usage: netns_exec.py CMD [ARGS...]", file=sys.stderr)
        return 2
    bring_loopback_up()
    problem = route_multicast_to_loopback()
    if problem is not None:
        print(f"netns_exec: {problem}", file=sys.stderr)
    os.execvp(argv[0], argv)
    return 127  # not reached: execvp raises on failure


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
