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

import logging
import os
import threading
from typing import Callable, Optional, Protocol, Union

from .._binding.constants import AbortCode, EventKind, StoreStatus
from .._binding.context import Deferred, LineContext, LocalNodeService
from .._binding.runtime import Event
from .._aio import LoopArg
from .._callbacks import CallbackList
from ..errors import AbortError, ConfigurationError
from .store_groups import DEFAULT_GROUPS, GroupTable
from .views import LocalNodeView

__all__ = ["MemoryStore", "ParameterStore", "StoreMedium", "StoreLike", "check_store",
           "is_path", "PARAMETER_GROUPS", "STORE_STATUS"]

log = logging.getLogger(__name__)


class StoreMedium(Protocol):
    """A store kept by the application (EEPROM, flash, a database...)."""

    def load(self) -> Optional[bytes]:
        ...

    def save(self, image: bytes) -> None:
        ...


#: What create_local_node(store=...) takes.
StoreLike = Union[str, bytes, "os.PathLike[str]", StoreMedium]

#: 0x1010 / 0x1011 parameter groups by name without a declaration: (group
#: mask, CiA 301 sub-index); see canopenfd.services.store_groups.
PARAMETER_GROUPS = DEFAULT_GROUPS

#: What a parameter load found (co_store_status_t), as the texts callbacks get:
#: the C name in lower case with dashes ('too-big'); IO says what failed.
STORE_STATUS = {int(status): {"IO": "io-error"}.get(status.name,
                                                   status.name.lower().replace("_", "-"))
                for status in StoreStatus}


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


def is_path(store: object) -> bool:
    # os.PathLike's isinstance() is true for any object with __fspath__
    return isinstance(store, (str, bytes, os.PathLike))


def check_store(store: Optional[StoreLike], where: str) -> Union[None, str, StoreMedium]:
    """A path (as str) or an object with load()/save(); ConfigurationError otherwise."""
    if store is None:
        return None
    if isinstance(store, (str, bytes, os.PathLike)):   # is_path(), spelled for mypy
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


class ParameterStore(LocalNodeService):
    """Where a local node keeps its saved parameters (0x1010 / 0x1011): a file
    the C stack writes itself, or a StoreMedium of the application, which
    Python feeds: its image at boot, each staged image after a save (events
    STORE tell what a load found)."""

    def __init__(self, context: LineContext, node: LocalNodeView,
                 store: Union[None, str, StoreMedium],
                 groups: Optional[GroupTable] = None) -> None:
        self._context = context
        self._groups = groups
        #: save_parameters / restore_defaults group names: (mask, sub-index)
        self.group_names = groups.names if groups is not None else PARAMETER_GROUPS
        self._node = node
        #: A file path, a StoreMedium, or None.
        self.store = store
        self._problems = CallbackList(f"node {node.node_id} store problem")
        # One image goes to the medium at a time: the application's save, a
        # network save and the stack's autonomous one each stage, persist and
        # finish under it.
        self._medium_lock = threading.RLock()
        context.subscribe(EventKind.STORE, self._event)
        context.subscribe(EventKind.STORE_PERSIST, self._autonomous_save)

    @property
    def path(self) -> Optional[str]:
        """The parameter file the C stack writes, None for none or a medium."""
        return self.store if isinstance(self.store, str) else None

    @property
    def medium(self) -> Optional[StoreMedium]:
        return None if self.store is None or isinstance(self.store, str) else self.store

    def open(self) -> None:
        """At boot, once the OD is defined: give an application medium's image
        to the runtime (an unreadable medium: the node runs on defaults), and
        the declared parameter groups."""
        if self._groups is not None:
            self._context.runtime.store_groups(
                self._context.index, self._groups.rows, self._groups.min_interval_ms,
                f"store groups of {self._where}")
        medium = self.medium
        if medium is None:
            return
        what = f"parameter store {self.store!r} of {self._where}"
        try:
            loaded = medium.load()
            status = StoreStatus.OK if loaded else StoreStatus.EMPTY
            image = bytes(loaded or b"")
            check_od = getattr(medium, "check_od", None)
            if loaded and callable(check_od) and self._node.od is not None:
                check_od(self._node.od)   # e.g. the text store: a stray entry at its line
        except ConfigurationError:
            # a medium that can tell what is wrong (a text store's file:line)
            # stops the boot: the device never starts half-configured
            raise
        except Exception:  # noqa: BLE001 - an unreadable medium: run on defaults, say so
            log.exception("%s: load() failed; the node starts from defaults", what)
            image, status = b"", StoreStatus.IO
        self._context.runtime.store_application(self._context.index, image, status, what)

    def _persist(self, what: str) -> Optional[int]:
        """Give the staged image to the application medium: 0, the CiA abort
        0x08000020 (data cannot be stored) when its save() raised, None when
        no image was staged."""
        medium = self.medium
        assert medium is not None
        image = self._context.runtime.store_staged(self._context.index, what)
        if image is None:
            return None
        try:
            medium.save(image)
        except Exception:  # noqa: BLE001 - reported as the CiA abort, logged with the cause
            log.exception("%s: the parameter store's save() failed", what)
            return int(AbortCode.DATA_STORE)
        return 0

    def _autonomous_save(self, event: Event) -> Deferred:
        """CO_EV_STORE_PERSIST: the stack saved autonomous groups into the
        staging image; a medium that refuses it gets them marked changed again
        (the stack retries one interval later)."""
        what = f"autonomous parameter save on {self._where}"

        def persist() -> None:
            with self._medium_lock:
                self._finish_autonomous(what)
        return persist

    def _finish_autonomous(self, what: str) -> bool:
        """Persist and finish the staged image if it is an autonomous save's;
        whether one was (under _medium_lock)."""
        context = self._context
        if self.medium is None or not context.runtime.store_autonomous_pending(context.index,
                                                                                  what):
            return False
        code = self._persist(what)
        if code is not None:
            context.runtime.store_finish(context.index, code == 0, what)
        return True

    def persist_request(self, token: int) -> Callable[[], None]:
        """A network save/restore waits until the image is on the medium (an
        OD request of kind STORE): what answers it."""
        what = f"0x1010/0x1011 over the network on {self._where}"

        def persist() -> None:
            with self._medium_lock:
                code = self._persist(what)
                self._context.runtime.od_answer(self._context.index, token, code or 0, what)
        return persist

    def save_or_restore(self, group: str, save: bool) -> None:
        """What a "save" to 0x1010 (save=True) or a "load" to 0x1011 does."""
        what = f"{'save_parameters' if save else 'restore_defaults'}({group!r}) on {self._where}"
        if group not in self.group_names:
            raise ConfigurationError(f"{what}: group must be one of "
                                     f"{', '.join(self.group_names)}")
        if not self._node.booted:
            raise ConfigurationError(f"{what}: the node is not booted yet")
        mask, sub = self.group_names[group]
        context = self._context
        with self._medium_lock:
            code = context.runtime.od_store(context.index, mask, save, what)
            if code == int(AbortCode.HARDWARE) and self._finish_autonomous(what):
                # an autonomous image was waiting for the medium: now it is there
                code = context.runtime.od_store(context.index, mask, save, what)
            if code == 0 and self.medium is not None:
                persisted = self._persist(what)
                if persisted is not None:
                    context.runtime.store_finish(context.index, persisted == 0, what)
                    code = persisted
        if code:
            raise AbortError(code, self._node.node_id, 0x1010 if save else 0x1011, sub, what)

    @property
    def status(self) -> Optional[str]:
        """What the last parameter load found; None without a store or before boot."""
        if self.store is None or not self._node.booted:
            return None
        context = self._context
        code = context.runtime.store_status(context.index, f"store status of {self._where}")
        return STORE_STATUS.get(code, str(code))

    def on_problem(self, callback: Callable[[str, int], None],
                   loop: LoopArg = None) -> Callable[[str, int], None]:
        return self._problems.add(callback, loop)

    def _event(self, event: Event) -> Deferred:
        """CO_EV_STORE: a = co_store_status_t, b = records skipped."""
        text = STORE_STATUS.get(event.a, str(event.a))
        if text in ("ok", "empty"):
            return None
        log.warning("%s: saved parameters in %s are %s; running on defaults",
                    self._where, self.store, text)
        skipped = event.b
        return lambda: self._problems.fire(text, skipped)

