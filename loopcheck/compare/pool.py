"""Process pools of the studies (``loopcheck cost``, ``loopcheck sweep``): the workers ended with the
parent, a dead worker noticed. (A run's file writers are forked by
``loopcheck.compare.output.write_folder`` itself.)

Each worker is a process of its own with a pipe to the parent and runs one task at a time; the
parent waits on the pipes and on the processes' sentinels together, so a worker that dies (killed
from outside, as the OOM killer does, or crashing in C) is seen at once: a fresh worker takes its
place and the task it had in flight runs once more; a task whose worker dies a second time is
given up and becomes ``lost(item, reason)`` (reason: "worker killed by signal N", or "worker
exited with status N"). A signal to the parent (Ctrl-C, SIGTERM raised as an exception) or a
consumer closing the generator ends every worker (SIGTERM, then SIGKILL), never waiting on one.
"""

from __future__ import annotations

import collections
import contextlib
from typing import Any, Callable, Iterable, Iterator

TRIES = 2
"""Runs of a task whose worker dies before it is given up (the decision: once more)."""
END_WAIT_S = 2.0
"""How long an ending worker is given to exit after SIGTERM, then SIGKILL."""


def ignore_interrupts() -> None:
    """Worker start-up: Ctrl-C (sent to the whole process group) is the parent's to handle;
    SIGTERM kills a worker outright (the parent ends its workers when it stops)."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def death_reason(exitcode: int | None) -> str:
    """Why a worker that ended with ``exitcode`` (multiprocessing's: -N for signal N) died."""
    if exitcode is not None and exitcode < 0:
        return f"worker killed by signal {-exitcode}"
    return f"worker exited with status {exitcode}"


def _serve(conn, func, initializer, initargs) -> None:
    """A worker: run each task received until told to stop (None) or the parent is gone."""
    initializer(*initargs)
    while True:
        try:
            task = conn.recv()
        except (EOFError, OSError):
            return
        if task is None:
            return
        seq, item = task
        try:
            reply = (seq, True, func(item))
        except BaseException as exc:  # noqa: BLE001 - the parent raises it
            reply = (seq, False, exc)
        try:
            conn.send(reply)
        except Exception as exc:  # noqa: BLE001 - a result or exception that does not pickle
            conn.send((seq, False, RuntimeError(f"{type(exc).__name__}: {exc}")))


class _Worker:
    def __init__(self, ctx, func, initializer, initargs):
        self.conn, child = ctx.Pipe()
        self.process = ctx.Process(target=_serve, args=(child, func, initializer, initargs), daemon=True)
        self.process.start()
        child.close()
        self.task: tuple[int, Any] | None = None  # (seq, item) in flight

    def end(self, wait: bool) -> None:
        """Stop the worker: asked to (``wait``, after a complete map) or ended (SIGTERM, SIGKILL)."""
        if wait and self.process.is_alive():
            with contextlib.suppress(OSError):
                self.conn.send(None)
            self.process.join(END_WAIT_S)
        if self.process.is_alive():
            self.process.terminate()
            self.process.join(END_WAIT_S)
        if self.process.is_alive():
            self.process.kill()
            self.process.join()
        self.conn.close()


def ordered_map(func: Callable[[Any], Any], items: Iterable[Any], workers: int,
                initializer: Callable[..., None] = ignore_interrupts, initargs: tuple = (), *,
                lost: Callable[[Any, str], Any] | None = None, start_method: str | None = None,
                ahead: int | None = None) -> Iterator[Any]:
    """func(item) for every item, computed by ``workers`` processes, yielded in the items' order
    as they complete (at most ``ahead``, default 4 per worker, computed past the one awaited).

    A worker that dies: its task runs once more on a fresh worker; if that one dies too, the
    task's result is ``lost(item, reason)`` (module docstring), or without ``lost`` a
    RuntimeError naming the reason. An exception raised by ``func`` is raised here. An
    exception in the parent (or closing the generator) ends the workers."""
    import multiprocessing
    from multiprocessing.connection import wait

    ctx = multiprocessing.get_context(start_method)
    ahead = 4 * workers if ahead is None else max(1, ahead)
    source = enumerate(items)
    exhausted = False
    queue: collections.deque[tuple[int, Any]] = collections.deque()  # tasks to run (again) first
    tries: dict[int, int] = {}
    done: dict[int, Any] = {}
    next_out = 0
    pool: list[_Worker] = []
    complete = False
    try:
        pool = [_Worker(ctx, func, initializer, initargs) for _ in range(workers)]
        while True:
            for w in pool:  # hand out tasks to the idle workers, retries first
                if w.task is not None:
                    continue
                if not queue:
                    in_flight = sum(x.task is not None for x in pool)
                    if exhausted or len(done) + in_flight >= ahead:
                        break
                    try:
                        queue.append(next(source))
                    except StopIteration:
                        exhausted = True
                        break
                w.task = queue.popleft()
                with contextlib.suppress(OSError):  # a worker dead already: seen below
                    w.conn.send(w.task)
            while next_out in done:
                yield done.pop(next_out)
                next_out += 1
            busy = [w for w in pool if w.task is not None]
            if not busy:
                if exhausted and not queue:
                    break
                continue
            ready = set(wait([w.conn for w in busy] + [w.process.sentinel for w in busy]))
            for i, w in enumerate(pool):
                if w.task is None:
                    continue
                got = False
                if w.conn in ready or w.process.sentinel in ready:
                    try:
                        if w.conn.poll():
                            seq, ok, value = w.conn.recv()
                            got = True
                    except Exception:  # noqa: BLE001
                        pass  # a reply cut by the worker's death: the worker is dead (below)
                if got:
                    if not ok:
                        raise value
                    done[seq] = value
                    w.task = None
                elif w.process.sentinel in ready or not w.process.is_alive():
                    w.process.join()
                    seq, item = w.task
                    reason = death_reason(w.process.exitcode)
                    w.task = None
                    w.end(wait=False)
                    pool[i] = _Worker(ctx, func, initializer, initargs)
                    tries[seq] = tries.get(seq, 0) + 1
                    if tries[seq] < TRIES:
                        queue.appendleft((seq, item))
                    elif lost is None:
                        raise RuntimeError(f"task {seq}: {reason}, {TRIES} times")
                    else:
                        done[seq] = lost(item, reason)
        complete = True
    finally:
        for w in pool:
            w.end(wait=complete)
