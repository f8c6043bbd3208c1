"""Bounded caches of what a process builds from a scene's meshes more than once.

A task builds several checkers of one scene (at several clearances, without some
obstacles: :meth:`flycrane.planning.validity.ValidityChecker.with_clearance`), and each of
them once read and parsed every mesh file and built every mesh's fcl hierarchy again: a mesh
of a million faces cost minutes and gigabytes around a plan of a second. What does not
depend on the clearance is kept here instead, in caches bounded in size (cachetools' least
recently used first out), so that a process holds at most a few meshes' worth.

Cached arrays are read-only: whoever gets one shares it.
"""

from __future__ import annotations

import hashlib
import threading
from collections.abc import Callable, Hashable
from typing import Generic, TypeVar

import numpy as np
from cachetools import LRUCache

V = TypeVar("V")


class SharedCache(Generic[V]):
    """A least-recently-used cache of values of at most ``size`` in all (``size_of`` each),
    behind a lock: cachetools' caches are not thread-safe. A value larger than ``size``
    alone is not kept. Two threads may both build a missing value; one of them is kept."""

    def __init__(self, size: int, size_of: Callable[[V], int]) -> None:
        self._cache: LRUCache[Hashable, V] = LRUCache(size, getsizeof=size_of)
        self._lock = threading.Lock()

    def get(self, key: Hashable) -> V | None:
        with self._lock:
            return self._cache.get(key)

    def put(self, key: Hashable, value: V) -> None:
        with self._lock:
            try:
                self._cache[key] = value
            except ValueError:  # larger than the whole cache
                pass

    def clear(self) -> None:
        with self._lock:
            self._cache.clear()

    def __len__(self) -> int:
        with self._lock:
            return len(self._cache)


def read_only(array: np.ndarray) -> np.ndarray:
    """``array`` made read-only (in place) and returned."""
    array.flags.writeable = False
    return array


def array_digest(*arrays: np.ndarray) -> bytes:
    """A digest of arrays' types, shapes and contents: equal for equal arrays, a key for
    what is built from them."""
    digest = hashlib.blake2b(digest_size=20)
    for array in arrays:
        array = np.ascontiguousarray(array)
        digest.update(f"{array.dtype.str}{array.shape};".encode())
        digest.update(array.reshape(-1).view(np.uint8).tobytes())
    return digest.digest()
