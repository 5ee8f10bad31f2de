"""Process pools of the studies (``xval cost``, ``xval sweep``): results in submission order,
the workers ended with the parent."""

from __future__ import annotations

from typing import Any, Callable, Iterable, Iterator


def ignore_interrupts() -> None:
    """Worker start-up: Ctrl-C (sent to the whole process group) is the parent's to handle;
    SIGTERM kills a worker outright (the parent ends its workers when it stops)."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def ordered_map(func: Callable[[Any], Any], items: Iterable[Any], workers: int,
                initializer: Callable[..., None] = ignore_interrupts, initargs: tuple = ()) -> Iterator[Any]:
    """func(item) for every item, computed by ``workers`` processes, yielded in the items' order
    as they complete. An exception in the parent (Ctrl-C, SIGTERM raised as an exception, the
    consumer closing the generator) ends the workers."""
    import multiprocessing

    pool = multiprocessing.Pool(workers, initializer=initializer, initargs=initargs)
    try:
        yield from pool.imap(func, items)
        pool.close()
    except BaseException:
        pool.terminate()
        raise
    finally:
        pool.join()
