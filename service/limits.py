"""Work requests may start, bounded: beyond a limit, 503 at once with Retry-After.

A request that waited for room would hold a thread of the server meanwhile (enough of them
and nothing else is answered, /healthz included); a refusal that says when to come back
costs nothing. Uploads (:class:`service.uploads.UploadRunner`) and what-ifs (/v1/statics)
are bounded so.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Iterator
from contextlib import contextmanager

from service.errors import ServiceBusyError


class Slots:
    """At most ``limit`` of ``what`` (a plural: "uploads") at once."""

    def __init__(self, limit: int, what: str, retry_after: float) -> None:
        self.limit, self.what = limit, what
        self.retry_after = str(math.ceil(retry_after))
        self._free = threading.BoundedSemaphore(limit)

    def take(self) -> None:
        """Take a slot, for :meth:`give_back` to return.

        Raises
        ------
        ServiceBusyError
            If ``limit`` are taken (503, Retry-After ``retry_after`` seconds).
        """
        if not self._free.acquire(blocking=False):
            raise ServiceBusyError(
                f"{self.limit} {self.what} are running; retry later",
                headers={"Retry-After": self.retry_after},
            )

    def give_back(self) -> None:
        self._free.release()

    @contextmanager
    def held(self) -> Iterator[None]:
        """A slot for the duration of the block (:meth:`take`)."""
        self.take()
        try:
            yield
        finally:
            self.give_back()
