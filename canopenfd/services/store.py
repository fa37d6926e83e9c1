"""Parameter stores a local node keeps its saved parameters (0x1010/0x1011) in.

A store is a file path (the C stack writes it atomically: temporary file,
fsync, rename, fsync of the directory) or any object with

    load() -> bytes or None     the image saved last (None: nothing saved)
    save(image: bytes) -> None  keep this image; return only once it would
                                survive a power cut, raise if it cannot

for EEPROM, flash or a database. The image is opaque (CRC-protected by the
stack, which detects a damaged or foreign one and then starts from defaults).
The stack never calls the store from its own thread: a save over the network
is answered only after `save()` returned (abort 0x08000020 if it raised), and
resets load the image the store holds.
"""

from __future__ import annotations

import os
import threading
from typing import Any, Optional, Union

from ..errors import ConfigurationError

StoreLike = Union[str, "os.PathLike[str]", Any]


class MemoryStore:
    """A store that keeps the image in memory (tests, examples, a base to
    copy for your medium). `saves` counts successful saves."""

    def __init__(self, image: Optional[bytes] = None) -> None:
        self.image = image
        self.saves = 0
        self._lock = threading.Lock()

    def load(self) -> Optional[bytes]:
        with self._lock:
            return self.image

    def save(self, image: bytes) -> None:
        with self._lock:
            self.image = bytes(image)
            self.saves += 1


def is_path(store: Any) -> bool:
    return isinstance(store, (str, bytes)) or hasattr(store, "__fspath__")


def check_store(store: Any, where: str) -> Any:
    """A path (as str) or an object with load()/save(); ConfigurationError otherwise."""
    if store is None:
        return None
    if is_path(store):
        path = os.fsdecode(os.fspath(store))
        if not path:
            raise ConfigurationError(f"{where}: store path is empty")
        return path
    missing = [name for name in ("load", "save") if not callable(getattr(store, name, None))]
    if missing:
        raise ConfigurationError(
            f"{where}: store must be a file path or an object with load() and save(image); "
            f"{type(store).__name__} has no {' and no '.join(missing)}()")
    return store
