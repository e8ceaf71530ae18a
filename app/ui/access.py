"""Who may use the studio page: viser's WebSocket has no login and accepts any Origin, so we add both.

- **Origin.** A browser tab on any site can open `ws://127.0.0.1:8080` and press the studio's buttons
  (the browser sends the tab's `Origin` with the handshake, and it cannot be forged from a page). The
  WebSocket is refused (403) unless `Origin` is the page's own (`http(s)://` + the `Host` it asked for).
- **Host.** A page on `http://evil.example:8080` whose name the attacker re-points at 127.0.0.1 (DNS
  rebinding) is same-origin with itself; so without a token only loopback host names are served.
- **Token** (when the studio listens beyond this machine, or drives a real robot): every request needs
  it. The printed link carries it once (`/?token=...`); that request sets an HttpOnly, SameSite=Strict
  cookie for this host and port and redirects to the bare page, so the token leaves the address bar.

The hook: viser 1.1.1 builds its server in `viser.infra.WebsockServer._background_worker` with
`websockets.asyncio.server.serve(..., process_request=<viser's HTTP file server>)`, which websockets
calls for every HTTP request and WebSocket handshake before anything reaches viser. `guarded_viser_server`
constructs the `ViserServer` while that one call composes `PageAccess.check` in front of viser's own
`process_request` (a subclass of websockets' `serve`); if viser ever stops calling it, construction
fails rather than serving an unguarded page.
"""

from __future__ import annotations

import http
import ipaddress
import secrets
import threading
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from http.cookies import CookieError, SimpleCookie
from urllib.parse import parse_qs, urlsplit

import viser
import websockets.asyncio.server as ws_server
from websockets.datastructures import Headers
from websockets.http11 import Request, Response

from core.errors import NotSupportedError

LOOPBACK_NAMES = frozenset({"localhost", "127.0.0.1", "::1"})
_CONSTRUCTION = threading.Lock()


def is_loopback(host: str) -> bool:
    """Whether `host` (a bind address or a Host header's name) names this machine only."""
    name = host.strip("[]").lower()
    if name in LOOPBACK_NAMES:
        return True
    try:
        return ipaddress.ip_address(name).is_loopback
    except ValueError:
        return False


def _host_name(host_header: str) -> str:
    """'127.0.0.1:8080' → '127.0.0.1', '[::1]:8080' → '::1'."""
    return urlsplit(f"//{host_header}").hostname or ""


def _header(request: Request, name: str) -> str | None:
    """The header's value; None if it is missing or sent more than once (a request to refuse)."""
    values = request.headers.get_all(name)
    return values[0] if len(values) == 1 else None


def _text(status: http.HTTPStatus, text: str, headers: dict[str, str] | None = None) -> Response:
    body = text.encode()
    all_headers = Headers({"Content-Type": "text/plain; charset=utf-8", "Content-Length": str(len(body)),
                           "Cache-Control": "no-store", **(headers or {})})
    return Response(status.value, status.phrase, all_headers, body)


@dataclass(frozen=True)
class PageAccess:
    """The policy: `token` None serves loopback host names to anyone on this machine with a matching
    Origin; with a token, any host name, but only with the token (link or cookie)."""

    token: str | None = None

    @classmethod
    def for_binding(cls, host: str, require_token: bool = False) -> PageAccess:
        """A token (random, for this process) when the page is reachable beyond this machine or asked for."""
        return cls(token=secrets.token_urlsafe(24) if require_token or not is_loopback(host) else None)

    @staticmethod
    def cookie_name(host_header: str) -> str:
        """One cookie per port: browsers share cookies between the ports of a host (two studios, the bridge)."""
        port = urlsplit(f"//{host_header}").port
        return f"htmpc_studio_{port or 80}"

    def check(self, request: Request) -> Response | None:
        """websockets' `process_request`: None lets the request through to viser, a Response refuses it."""
        host = _header(request, "Host")
        if host is None:
            return _text(http.HTTPStatus.BAD_REQUEST, "exactly one Host header, please\n")
        if self.token is None and not is_loopback(_host_name(host)):
            return _text(http.HTTPStatus.FORBIDDEN, f"this studio serves this machine only, not the host {host!r}\n")
        upgrade = request.headers.get("Upgrade", "").lower() == "websocket"
        if upgrade and _header(request, "Origin") not in (f"http://{host}", f"https://{host}"):
            return _text(http.HTTPStatus.FORBIDDEN, "WebSocket refused: the page's Origin is not this studio\n")
        if self.token is None:
            return None
        link_token = parse_qs(urlsplit(request.path).query).get("token", [""])[0]
        if not upgrade and link_token:
            return self._redeem(link_token, host)
        if self._matches(self._cookie(request, host)):
            return None
        return _text(http.HTTPStatus.UNAUTHORIZED, "this studio needs its access link: open the URL it printed "
                                                   "at start (http://HOST:PORT/?token=...)\n")

    def _matches(self, candidate: str) -> bool:
        return bool(candidate) and secrets.compare_digest(candidate.encode(), (self.token or "").encode())

    def _cookie(self, request: Request, host: str) -> str:
        try:
            jar = SimpleCookie("; ".join(request.headers.get_all("Cookie")))
        except CookieError:
            return ""
        morsel = jar.get(self.cookie_name(host))
        return morsel.value if morsel is not None else ""

    def _redeem(self, link_token: str, host: str) -> Response:
        """The access link: set the cookie and send the browser to the bare page (token out of the URL)."""
        if not self._matches(link_token):
            return _text(http.HTTPStatus.UNAUTHORIZED, "wrong access token: open the URL the studio printed\n")
        cookie = f"{self.cookie_name(host)}={self.token}; Path=/; HttpOnly; SameSite=Strict"
        return _text(http.HTTPStatus.SEE_OTHER, "access granted\n", {"Location": "/", "Set-Cookie": cookie})


ProcessRequest = Callable[[ws_server.ServerConnection, Request], Awaitable[Response | None] | Response | None]
"""websockets' hook that may answer a handshake's HTTP request itself."""


class _GuardedServe(ws_server.serve):
    """websockets' `serve` with a check in front of the `process_request` viser passes (viser's only)."""

    check: Callable[[Request], Response | None] | None = None
    installed = False

    def __init__(self, handler, *args, process_request: ProcessRequest | None = None, **kwargs) -> None:
        check = type(self).check
        if (check is not None and process_request is not None
                and getattr(process_request, "__module__", "") == "viser.infra._infra"):
            inner = process_request

            def guarded(connection: ws_server.ServerConnection, request: Request):
                refused = check(request)
                return refused if refused is not None else inner(connection, request)

            process_request = guarded
            type(self).installed = True
        super().__init__(handler, *args, process_request=process_request, **kwargs)


def guarded_viser_server(access: PageAccess, **kwargs) -> viser.ViserServer:
    """A `ViserServer(**kwargs)` whose every HTTP request and WebSocket handshake `access` checks first."""
    with _CONSTRUCTION:
        original = ws_server.serve
        guard = type("_Guard", (_GuardedServe,), {"check": staticmethod(access.check), "installed": False})
        ws_server.serve = guard
        try:
            server = viser.ViserServer(**kwargs)
        finally:
            ws_server.serve = original
    if not guard.installed:
        server.stop()
        raise NotSupportedError("viser no longer serves through websockets.asyncio.server.serve with its own "
                           "process_request: the studio page cannot be guarded, so it is not served")
    return server
