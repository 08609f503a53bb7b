"""Read ahead: a chunked stream's next items made on a second thread while the consumer works on this one.

Used where reading a chunk (bytes, lexing: C or numpy, which release the interpreter lock) and
using it (replay, post-processing) are both heavy: ``verify`` and ``convert``. The items come in
order, and an error of the producer is raised where its item would have come, so what a consumer
sees (values, messages, which error comes first) does not depend on the thread.

A thread shares the interpreter lock: the Python between numpy's loops on both sides takes turns.
(A forked reading process ran both really at once, but pickling the chunks through its pipe was
about a quarter of a large conversion's profile, and the whole fork bought well under a second.)
"""

from __future__ import annotations

import threading
from collections.abc import Iterable, Iterator
from queue import Full, Queue
from typing import Any, TypeVar

__all__ = ["read_ahead"]

_Item = TypeVar("_Item")


def read_ahead(items: Iterable[_Item], depth: int = 2) -> Iterator[_Item]:
    """The items of ``items`` in order, produced by a thread up to ``depth`` ahead of the consumer:
    reading and lexing the next chunk of a program overlaps the replay of this one (numpy releases
    the interpreter lock in both). An exception of the producer is raised here, where its item
    would have come; a consumer that stops early stops the producer.
    """
    queue: Queue[tuple[str, Any]] = Queue(maxsize=max(1, depth))
    stop = threading.Event()

    def put(entry: tuple[str, Any]) -> bool:
        while not stop.is_set():
            try:
                queue.put(entry, timeout=0.05)
                return True
            except Full:
                continue
        return False

    def produce() -> None:
        try:
            for item in items:
                if not put(("item", item)):
                    return
            put(("end", None))
        except Exception as exc:
            put(("error", exc))

    thread = threading.Thread(target=produce, name="read-ahead", daemon=True)
    thread.start()
    try:
        while True:
            kind, value = queue.get()
            if kind == "item":
                yield value
            elif kind == "error":
                raise value
            else:
                return
    finally:
        stop.set()
        thread.join()
