"""Process pools of the studies (``loopcheck cost``, ``loopcheck sweep``): the workers ended with the
parent. (A run's file writers are forked by ``loopcheck.compare.output.write_folder`` itself.)"""

from __future__ import annotations

import contextlib
from typing import Any, Callable, Iterable, Iterator


def ignore_interrupts() -> None:
    """Worker start-up: Ctrl-C (sent to the whole process group) is the parent's to handle;
    SIGTERM kills a worker outright (the parent ends its workers when it stops)."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


@contextlib.contextmanager
def worker_pool(workers: int, initializer: Callable[..., None] = ignore_interrupts, initargs: tuple = (),
                start_method: str | None = None) -> Iterator[Any]:
    """A ``multiprocessing.Pool`` of ``workers`` processes (``start_method``: "fork", ... or the
    platform's default) for the block: closed and joined when the block ends, terminated when it
    raises (Ctrl-C, SIGTERM raised as an exception, a consumer closing a generator)."""
    import multiprocessing

    pool = multiprocessing.get_context(start_method).Pool(workers, initializer=initializer, initargs=initargs)
    try:
        yield pool
        pool.close()
    except BaseException:
        pool.terminate()
        raise
    finally:
        pool.join()


def ordered_map(func: Callable[[Any], Any], items: Iterable[Any], workers: int,
                initializer: Callable[..., None] = ignore_interrupts, initargs: tuple = ()) -> Iterator[Any]:
    """func(item) for every item, computed by ``workers`` processes, yielded in the items' order
    as they complete. An exception in the parent ends the workers."""
    with worker_pool(workers, initializer, initargs) as pool:
        yield from pool.imap(func, items)
