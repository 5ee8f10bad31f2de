"""A Dask cluster for ``loopcheck sweep --scheduler ADDRESS`` (the optional ``distributed`` extra;
nothing imports Dask otherwise): the scheduler refused up front when Dask is missing or the address
is not a scheduler with workers, and chunks of variants run as Dask tasks whose rows come back in
submission order (the module docstring of :mod:`loopcheck.compare.sweep`)."""

from __future__ import annotations

import time
from typing import Any, Callable, Iterator, Mapping

DASK_EXTRA = "pip install -e '.[distributed]' in loopcheck's checkout"
CONNECT_TIMEOUT_S = 10.0
CHUNKS_IN_FLIGHT = 4
"""Dask tasks (chunks) submitted at a time per worker thread: enough to keep each busy while the
earliest is read back, few enough that results waiting their turn stay a bounded handful."""


class SchedulerError(ValueError):
    """``--scheduler``: Dask is not installed, the scheduler cannot be reached, or the cluster lost a
    chunk (one line, exit status 2)."""


def require_dask() -> None:
    """Refuse ``--scheduler`` without the ``distributed`` extra (checked before any work)."""
    try:
        import distributed  # noqa: F401
    except ImportError:
        raise SchedulerError(f"--scheduler needs Dask, which is not installed: {DASK_EXTRA}") from None


HANDSHAKE_MAX_BYTES = 1 << 20  # a Dask handshake is ~100 bytes; more is some other service's data


def _probe_scheduler(address: str, host: str, port: int, deadline: float, timeout: float) -> None:
    """Refuse a TCP address that is not a Dask scheduler before Dask talks to it, by ``deadline``.

    A Dask server sends its handshake as soon as it accepts a connection: an 8-byte length,
    then that many bytes. Dask's own client waits for it without a time limit (a silent
    service hung ``loopcheck sweep`` for 681 s) and allocates whatever length it reads (an HTTP
    server's reply made it a MemoryError). Here the wait is bounded and the length checked."""
    import socket
    import struct

    def fail(why: str):
        return SchedulerError(f"--scheduler {address}: {why}")

    def left() -> float:
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            raise fail(f"no Dask scheduler there (no handshake within {timeout:g} s)")
        return remaining

    def read(sock, n: int) -> bytes:
        data = b""
        while len(data) < n:
            sock.settimeout(left())
            try:
                chunk = sock.recv(n - len(data))
            except socket.timeout:
                continue  # left() raises once the deadline has passed
            if not chunk:
                raise fail("not a Dask scheduler (the service closed the connection)")
            data += chunk
        return data

    try:
        sock = socket.create_connection((host, port), timeout=left())
    except OSError as exc:
        raise fail(f"cannot connect ({exc.strerror or ' '.join(str(exc).split())})") from None
    with sock:
        try:
            (size,) = struct.unpack("<Q", read(sock, 8))
            if not 0 < size <= HANDSHAKE_MAX_BYTES:
                raise fail("not a Dask scheduler (it did not answer with a Dask handshake)")
            read(sock, size)
        except OSError as exc:
            raise fail(f"cannot connect ({exc.strerror or ' '.join(str(exc).split())})") from None


def connect(address: str, timeout: float | None = None):
    """A :class:`distributed.Client` of the scheduler at ``address`` with at least one worker,
    or :class:`SchedulerError` within about ``timeout`` seconds (default :data:`CONNECT_TIMEOUT_S`)."""
    require_dask()
    timeout = CONNECT_TIMEOUT_S if timeout is None else timeout
    from distributed import Client
    from distributed.comm import get_address_host_port

    try:  # a malformed address first: a Client that fails on one hangs in its __del__
        host, port = get_address_host_port(address)
    except ValueError as exc:
        raise SchedulerError(f"--scheduler {address}: not a scheduler address like tcp://host:8786 "
                             f"({' '.join(str(exc).split())})") from None
    deadline = time.monotonic() + timeout
    if address.startswith("tcp://") or "://" not in address:
        _probe_scheduler(address, host, port, deadline, timeout)
    try:
        client = Client(address, timeout=max(deadline - time.monotonic(), 1.0), set_as_default=False)
    except Exception as exc:  # noqa: BLE001 - OSError, TimeoutError...
        raise SchedulerError(f"--scheduler {address}: cannot connect "
                             f"({type(exc).__name__}: {' '.join(str(exc).split())})") from None
    try:
        client.wait_for_workers(1, timeout=timeout)
    except Exception:  # noqa: BLE001
        client.close()
        raise SchedulerError(f"--scheduler {address}: the scheduler has no workers "
                             f"(none joined within {timeout:g} s)") from None
    return client


def dask_threads(client) -> int:
    """Worker threads of a Dask cluster (what the chunk size and the tasks in flight scale with)."""
    return max(1, sum(client.nthreads().values()))


def dask_rows(client, chunk: Callable[..., list[dict[str, Any]]], data: Mapping[str, Any], args: tuple,
              tasks: Iterator[tuple[int, list[dict[str, float]]]], in_flight: int) -> Iterator[dict[str, Any]]:
    """The rows of ``tasks`` run on ``client``'s cluster, in variant order: each task ``(start,
    values)`` is ``chunk(start, values, data, *args)`` on a worker, with ``data`` sent once to every
    worker; the futures are read in submission order, at most ``in_flight`` submitted at a time, the
    next submitted as the earliest comes back (so the CSV streams and memory stays flat)."""
    from collections import deque

    [shared] = client.scatter([dict(data)], broadcast=True)  # the scene data: sent once to every worker
    pending: deque = deque()

    def submit() -> bool:
        task = next(tasks, None)
        if task is None:
            return False
        start, values = task
        pending.append(client.submit(chunk, start, values, shared, *args, pure=False))
        return True

    try:
        while len(pending) < in_flight and submit():
            pass
        while pending:
            future = pending.popleft()
            try:
                rows = future.result()
            except Exception as exc:  # noqa: BLE001 - the cluster's (a variant's own errors are rows)
                raise SchedulerError(f"a chunk of variants failed on the Dask cluster ({type(exc).__name__}: "
                                     f"{' '.join(str(exc).split())})") from exc
            submit()
            yield from rows
    finally:
        try:  # interrupted or failed: nothing left running for this sweep
            client.cancel(list(pending) + [shared])
        except Exception:  # noqa: BLE001 - the scheduler is gone: nothing to cancel
            pass
