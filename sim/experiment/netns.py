"""A network namespace of its own for a local Ray cluster, so that nothing it serves is reachable
from another machine.

Ray 2.60's GCS server, raylets and workers listen on every interface whatever node address they
are given (measured: ``ss -ltnp`` shows them on ``*:PORT`` with ``--node-ip-address
127.0.0.1``). Started from a thread that has entered a fresh network namespace, which holds only
a loopback interface, "every interface" is the loopback: the cluster's processes inherit the
namespace, and the driver talks to them over it. The thread returns to its own namespace when
the block ends. Making a namespace needs CAP_SYS_ADMIN (root, or a container that grants it);
where it cannot be made, the block runs as before and says once, in one line, what listens.
"""

from __future__ import annotations

import ctypes
import fcntl
import os
import socket
import struct
import sys
from collections.abc import Iterator
from contextlib import contextmanager

CLONE_NEWNET = 0x40000000
SIOCSIFFLAGS = 0x8914
IFF_UP, IFF_LOOPBACK, IFF_RUNNING = 0x1, 0x8, 0x40
_warned = False


def _libc():
    return ctypes.CDLL(None, use_errno=True)


def _loopback_up() -> None:
    """Bring up the new namespace's loopback interface (it starts down)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        flags = IFF_UP | IFF_LOOPBACK | IFF_RUNNING
        fcntl.ioctl(probe, SIOCSIFFLAGS, struct.pack("16sH14s", b"lo", flags, bytes(14)))


def _enter() -> int | None:
    """Move this thread into a new network namespace with its loopback up; the descriptor of
    the namespace it left (to return to), or None where it may not."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        own = os.open("/proc/thread-self/ns/net", os.O_RDONLY)
    except OSError:
        return None
    if _libc().unshare(CLONE_NEWNET) != 0:
        os.close(own)
        return None
    try:
        _loopback_up()
    except OSError:
        _leave(own)
        return None
    return own


def _leave(own: int) -> None:
    try:
        if _libc().setns(own, CLONE_NEWNET) != 0:
            error = ctypes.get_errno()
            raise OSError(error, f"cannot return to this thread's network namespace ({error})")
    finally:
        os.close(own)


@contextmanager
def private_network(why_not: str | None = None) -> Iterator[bool]:
    """Run the block in a network namespace of its own (True), or, where ``why_not`` says the
    work needs the machine's network or a namespace cannot be made, as before (False), with one
    warning a process naming what listens on every interface."""
    global _warned
    own = None if why_not else _enter()
    if own is None:
        if not _warned:
            reason = why_not or "making a network namespace needs root or CAP_SYS_ADMIN"
            print(
                "warning: --backend ray: Ray's servers listen on every interface of this "
                f"machine ({reason}); for a cluster bound as you choose, start one and pass "
                "--ray-address",
                file=sys.stderr,
            )
            _warned = True
        yield False
        return
    try:
        yield True
    finally:
        _leave(own)
