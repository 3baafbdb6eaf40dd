"""Clients closed at interpreter exit (see python/src/lifecycle.rs).

Every client a constructor returns is tracked here weakly (a client nobody holds is not kept
alive); at exit, ``close_all`` closes each one still alive, which announces the disconnect where
the protocol has one (WSG 0x07, GCL ``BYE()``, GRIPLINK ``BYE``), so that the gripper does not go
into FAST STOP. Closing is idempotent: a client the program closed itself is left as it is.
"""

from __future__ import annotations

import weakref
from typing import Any

_clients: weakref.WeakSet[Any] = weakref.WeakSet()


def track(client: Any) -> None:
    """Tracks ``client`` (a blocking or asyncio client) for ``close_all``."""
    _clients.add(client)


def close_all() -> None:
    """Closes every tracked client still alive (``atexit``); errors are ignored: the process is
    ending, and a client whose connection is gone has nothing left to announce."""
    for client in list(_clients):
        try:
            # An asyncio client is closed through its blocking view: no event loop runs at exit.
            blocking = getattr(client, "blocking", client)
            if not blocking.is_closed:
                blocking.close()
        except Exception:  # noqa: BLE001 (see the docstring)
            pass
