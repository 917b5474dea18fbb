"""What an environment keeps in memory of the containers it has met, and for how long.

An environment over a family of containers (``objects="procedural:train"``, 200 members)
meets a new pair of them at almost every reset. Each container's labelled asset and
signed-distance field take 10-30 MB; kept for good, they grew one process past 15 GB in a
soak. A :class:`ContainerStore` keeps them for the containers used last, a bounded number,
and loads an evicted one again from the on-disk caches when it is met again (tens of
milliseconds: nothing is recomputed; ``pour-gym build-assets`` fills those caches ahead
of a run). The envs of a native vector env share one store, so a container costs its
memory once per process, not once per env.
"""

from __future__ import annotations

import gc
import threading
from collections import OrderedDict
from collections.abc import Callable
from typing import TypeVar

from pour_gym.errors import InputError

T = TypeVar("T")

# Containers an environment keeps loaded by default: an episode uses two, and a catalogue
# split (at most 12 containers) stays loaded whole.
KEPT = 16
# Dropped containers between two collections of their garbage (release): about 25 MB each
# waits for it, and a collection takes some 40 ms with an env's objects, under Python's lock.
COLLECT_EVERY = 8


class ContainerStore:
    """Loaded data of the containers used last, by container name and kind.

    Thread-safe: the envs of a vector env reset in threads of one process.

    Args:
        capacity: containers kept at most (all their kinds together); the one used least
            recently goes first.
    """

    def __init__(self, capacity: int = KEPT):
        if int(capacity) < 1:
            raise InputError(f"a container store keeps at least one container, not {capacity}")
        self.capacity = int(capacity)
        self._entries: OrderedDict[str, dict[str, object]] = OrderedDict()
        self._small: dict[tuple[str, str], object] = {}
        self._lock = threading.Lock()
        self._dropped = 0  # containers dropped since the last collection

    def get(self, name: str, kind: str, load: Callable[[], T], small: bool = False) -> T:
        """The ``kind`` of container ``name`` (``load()`` makes it when it is not kept).

        Args:
            name: the container's spec, as the environment was given it.
            kind: what of it (``"asset"``, ``"field"``, ...).
            load: makes the value; called outside the lock (loads may take seconds), so two
                threads may both load a value the first time: either result is kept.
            small: a value of a few kB that takes long to make and has no disk cache (what
                a source holds by tilt: 0.1-1 s each): kept for good, outside the
                capacity, so a container met again after its eviction does not make it
                again (200 containers: a few hundred kB).
        """
        if small:
            with self._lock:
                if (name, kind) in self._small:
                    return self._small[name, kind]  # type: ignore[return-value]
            value = load()
            with self._lock:
                return self._small.setdefault((name, kind), value)  # type: ignore[return-value]
        with self._lock:
            entry = self._entries.get(name)
            if entry is not None:
                self._entries.move_to_end(name)
                if kind in entry:
                    return entry[kind]  # type: ignore[return-value]
        value = load()
        with self._lock:
            entry = self._entries.setdefault(name, {})
            entry.setdefault(kind, value)
            self._entries.move_to_end(name)
            while len(self._entries) > self.capacity:
                self._entries.popitem(last=False)
                self._dropped += 1
            value = entry[kind]
            collect = self._dropped >= COLLECT_EVERY
            if collect:
                self._dropped = 0
        if collect:
            release()
        return value  # type: ignore[return-value]

    def adopt(self, other: ContainerStore) -> None:
        """Keep what ``other`` holds too (an env that joins a shared store brings its own)."""
        with other._lock:
            entries = [(name, dict(entry)) for name, entry in other._entries.items()]
            small = dict(other._small)
        with self._lock:
            for key, value in small.items():
                self._small.setdefault(key, value)
        for name, entry in entries:
            for kind, value in entry.items():
                self.get(name, kind, lambda value=value: value)

    def __len__(self) -> int:
        """Containers kept."""
        return len(self._entries)

    def __contains__(self, name: str) -> bool:
        return name in self._entries

    def clear(self) -> None:
        """Drop everything kept."""
        with self._lock:
            self._entries.clear()
            self._small.clear()
        release()


def release() -> None:
    """Free what dropped containers held now rather than at the next full collection.

    A trimesh mesh refers to itself (its cache), so a dropped asset's mesh is freed only
    by Python's cycle collector, whose full passes come seldom: an env over a family,
    dropping a container at most resets, would hold several hundred MB of such garbage at
    a time. A store collects after every :data:`COLLECT_EVERY` containers it dropped.
    """
    gc.collect()
