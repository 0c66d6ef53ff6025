"""A least-recently-used cache of encoded tiles, bounded by bytes (not entries)."""

from __future__ import annotations

import threading
from collections import OrderedDict


class ByteLRU:
    """Maps keys to bytes; holds at most ``capacity`` bytes of values, evicting the least
    recently used. A value larger than the capacity is not kept. Thread-safe."""

    def __init__(self, capacity: int):
        self.capacity = int(capacity)
        self.size = 0
        self.hits = 0
        self.misses = 0
        self._items: OrderedDict = OrderedDict()
        self._lock = threading.Lock()

    def get(self, key):
        with self._lock:
            value = self._items.get(key)
            if value is None:
                self.misses += 1
                return None
            self._items.move_to_end(key)
            self.hits += 1
            return value

    def put(self, key, value: bytes) -> None:
        n = len(value)
        with self._lock:
            old = self._items.pop(key, None)
            if old is not None:
                self.size -= len(old)
            if n > self.capacity:
                return
            self._items[key] = value
            self.size += n
            while self.size > self.capacity:
                _, v = self._items.popitem(last=False)
                self.size -= len(v)

    def __len__(self) -> int:
        return len(self._items)
