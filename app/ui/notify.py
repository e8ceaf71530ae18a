"""Operator notifications: errors become toasts in every browser, never a dead page."""

from __future__ import annotations

import functools
import logging
from collections.abc import Callable
from typing import Any

import viser

from app.ui.colors import NamedColour

log = logging.getLogger(__name__)


def notify_all(server: viser.ViserServer, title: str, body: str, color: NamedColour = "red") -> None:
    """Show a notification in every connected browser."""
    for client in server.get_clients().values():
        try:
            client.add_notification(title, body, auto_close_seconds=8.0, color=color)
        except Exception:  # a client that just left
            log.debug("notification to a departed client dropped")


def guarded(server: viser.ViserServer, what: str) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """Decorator for GUI callbacks: an exception becomes a notification naming the action."""
    def wrap(fn: Callable[..., Any]) -> Callable[..., Any]:
        @functools.wraps(fn)
        def inner(*args: Any, **kwargs: Any) -> Any:
            try:
                return fn(*args, **kwargs)
            except Exception as err:
                log.warning("%s failed: %s", what, err)
                notify_all(server, f"{what} failed", str(err))
                return None
        return inner
    return wrap
