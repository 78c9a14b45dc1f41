"""Camera pictures already drawn in this process, kept for the next identical view (issue 51).

An ablation's arms run the same seeds: their rooms are laid out alike, and a step that leaves
every body where another arm's step left it asks for the same picture. In the shipped scenarios a
quarter to a third of the pictures repeat (by hand, cells in turn: ``mo`` 26%, ``of`` 31% of about
400), and TinyRenderer's fill of the floor and walls makes a picture 12-15 ms of CPU whatever is in
it. A repeat is answered from here instead, with the same pixels.

**The key is everything the picture is drawn from**, read back from Bullet after the scene handed
it every placement (:meth:`.scene.Scene.flush`):

* the room as built: its options (JSON; the bodies, their sizes and colours follow from them) and
  the camera's size and projection;
* the view: the camera's eye and where it looks (from the robot's pose);
* the position and orientation of every body in the client, as Bullet holds them (exact doubles,
  compared byte for byte, never hashed: two keys are equal only when every number is);
* the balls left out of the picture (derived from the poses, kept in the key all the same).

Nothing else reaches TinyRenderer: no light, texture or colour is changed between pictures (a ball
left out is restored after its picture). Tests compare whole trials with the cache on and off, and
a picture from one room with another room's at the same poses.

**Memory:** pictures are kept zlib-compressed (level 1: a 320x240 picture of a room is a few KB, at
about 0.4 ms to compress and 0.3 ms to restore), at most :data:`MAX_BYTES` per process, the least
recently used dropped first. ``SAFEEMBODAI_PICTURE_CACHE_MB=0`` turns it off (any other number sets
the budget). Shared by every room of the process behind one lock; a worker process keeps its own.
"""

from __future__ import annotations

import os
import threading
import zlib
from collections import OrderedDict

import numpy as np

#: The environment variable that sets the budget in MB (0: off).
BUDGET_VARIABLE = "SAFEEMBODAI_PICTURE_CACHE_MB"
#: The default budget: about 4,000 pictures of the shipped rooms.
MAX_BYTES = 16 * 2**20
_LEVEL = 1


def _budget_from_environment() -> int:
    text = os.environ.get(BUDGET_VARIABLE, "").strip()
    if not text:
        return MAX_BYTES
    try:
        megabytes = float(text)
    except ValueError:
        raise ValueError(f"{BUDGET_VARIABLE}={text!r}: not a number of MB (0 turns the picture cache off)") from None
    if not megabytes >= 0 or megabytes == float("inf"):
        raise ValueError(f"{BUDGET_VARIABLE}={text!r}: must be a finite number of MB, 0 or more")
    return int(megabytes * 2**20)


class PictureCache:
    """Pictures by key (bytes), zlib-compressed, least recently used dropped beyond ``max_bytes``."""

    def __init__(self, max_bytes: int | None = None) -> None:
        self.max_bytes = _budget_from_environment() if max_bytes is None else max_bytes
        self._pictures: OrderedDict[bytes, tuple[bytes, tuple[int, ...]]] = OrderedDict()
        self._bytes = 0
        self._lock = threading.Lock()
        self.hits = 0
        self.misses = 0

    @property
    def enabled(self) -> bool:
        return self.max_bytes > 0

    def get(self, key: bytes) -> np.ndarray | None:
        """The picture kept under ``key`` (a fresh array the caller may change), or None."""
        with self._lock:
            kept = self._pictures.get(key)
            if kept is None:
                self.misses += 1
                return None
            self._pictures.move_to_end(key)
            self.hits += 1
        data, shape = kept
        return np.frombuffer(zlib.decompress(data), dtype=np.uint8).reshape(shape).copy()

    def put(self, key: bytes, pixels: np.ndarray) -> None:
        """Keep ``pixels`` (``uint8``) under ``key``; the least recently used go beyond the budget."""
        data = zlib.compress(np.ascontiguousarray(pixels, dtype=np.uint8).tobytes(), _LEVEL)
        size = len(data) + len(key)
        if size > self.max_bytes:
            return
        with self._lock:
            old = self._pictures.pop(key, None)
            if old is not None:
                self._bytes -= len(old[0]) + len(key)
            self._pictures[key] = (data, tuple(pixels.shape))
            self._bytes += size
            while self._bytes > self.max_bytes:
                dropped_key, (dropped, _) = self._pictures.popitem(last=False)
                self._bytes -= len(dropped) + len(dropped_key)

    def clear(self) -> None:
        with self._lock:
            self._pictures.clear()
            self._bytes = 0
            self.hits = self.misses = 0

    def __len__(self) -> int:
        return len(self._pictures)

    @property
    def size_bytes(self) -> int:
        return self._bytes


#: The process's pictures, shared by every room in it.
PICTURES = PictureCache()
