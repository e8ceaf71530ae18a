"""The bridge's bearer token: where it comes from, and the checks that require it.

Order: an explicit token (configuration, `BridgeServer(token=...)`), else `HTMPC_BRIDGE_TOKEN` from
the environment, else the user's token file (`$XDG_CONFIG_HOME/htmpc-studio/bridge_token`, by default
`~/.config/...`), else a new random token, saved there (mode 0600). The robot link and every request
that changes anything need `Authorization: Bearer <token>`; a missing or wrong token is answered 401.

The token moves a robot, so it is never printed in full (`masked` shows a prefix), never taken from a
command line (visible to every user in `ps`), and a token file that group or others may read, or that
another user owns, is refused (as ssh refuses such a private key): a warning would let a leaked token
keep working.
"""

from __future__ import annotations

import logging
import os
import secrets
import stat
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

from fastapi import Depends, HTTPException, Request, status
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer

from core.atomic_file import write_text_atomic

log = logging.getLogger(__name__)

TOKEN_ENV = "HTMPC_BRIDGE_TOKEN"
MIN_TOKEN_CHARS = 16
SHOWN_CHARS = 4
"""How much of a token is ever printed."""
BEARER = HTTPBearer(auto_error=False, description="the bridge token (see docs/bridge.md, 'Auth')")
"""Declares the scheme in the OpenAPI schema; the check itself is `require_token`."""


def default_token_file() -> Path:
    """`$XDG_CONFIG_HOME/htmpc-studio/bridge_token` (XDG default `~/.config`)."""
    base = os.environ.get("XDG_CONFIG_HOME") or str(Path.home() / ".config")
    return Path(base) / "htmpc-studio" / "bridge_token"


def masked(token: str) -> str:
    """What may be printed of a token: its first characters and its length."""
    return f"{token[:SHOWN_CHARS]}… ({len(token)} characters)"


@dataclass(frozen=True)
class Token:
    """The token and where it came from ('config', 'environment', 'file' or 'generated')."""

    value: str
    source: str
    path: Path | None = None

    def __repr__(self) -> str:  # never the token itself in logs or tracebacks
        return f"Token({masked(self.value)!r}, source={self.source!r}, path={self.path!r})"

    def matches(self, credentials: str | None) -> bool:
        """Whether `credentials` is this token (constant-time comparison)."""
        return bool(credentials) and secrets.compare_digest(credentials.strip().encode(), self.value.encode())

    def matches_header(self, authorization: str | None) -> bool:
        """Whether an `Authorization` header value is 'Bearer <this token>'."""
        scheme, _, credentials = (authorization or "").strip().partition(" ")
        return scheme.lower() == "bearer" and self.matches(credentials)

    def describe(self) -> str:
        """Where the token is, for the operator (masked): how a driver on this machine gets it."""
        if self.path is not None:
            return (f"token {masked(self.value)} in {self.path}; a driver on this machine reads it from there "
                    f"(or: export {TOKEN_ENV}=\"$(cat {self.path})\")")
        if self.source == "environment":
            return f"token {masked(self.value)} from {TOKEN_ENV}; give the driver the same variable"
        return f"token {masked(self.value)} as configured"


def _checked(value: str, source: str) -> str:
    value = value.strip()
    if len(value) < MIN_TOKEN_CHARS or any(c.isspace() for c in value):
        raise ValueError(f"bridge token from {source} must be at least {MIN_TOKEN_CHARS} characters, no spaces")
    return value


def read_token_file(path: Path) -> str:
    """The token in `path`; ValueError if others may read the file or another user owns it."""
    info = path.stat()
    if info.st_mode & 0o077:
        raise ValueError(f"bridge token file {path} is readable by others (mode {stat.S_IMODE(info.st_mode):04o}); "
                         f"anyone who reads it can move the robot. Fix: chmod 600 {path}")
    if hasattr(os, "getuid") and info.st_uid != os.getuid():
        raise ValueError(f"bridge token file {path} belongs to another user (uid {info.st_uid}); use your own")
    return _checked(path.read_text(encoding="utf-8"), str(path))


def _generate(path: Path) -> Token:
    value = secrets.token_hex(24)
    path.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
    write_text_atomic(path, value + "\n", permissions=0o600, exclusive=True)
    token = Token(value, "generated", path)
    print(f"hardware bridge: generated a new token in {path} (mode 0600): {masked(value)}", flush=True)
    return token


def resolve_token(explicit: str | None = None, token_file: Path | None = None,
                  environ: Mapping[str, str] | None = None) -> Token:
    """The token by the order above; generates and saves one on first run."""
    environ = os.environ if environ is None else environ
    if explicit:
        return Token(_checked(explicit, "configuration"), "config")
    if environ.get(TOKEN_ENV):
        return Token(_checked(environ[TOKEN_ENV], TOKEN_ENV), "environment")
    path = token_file or default_token_file()
    if path.exists():
        return Token(read_token_file(path), "file", path)
    return _generate(path)


def read_token(token_file: Path | None = None, environ: Mapping[str, str] | None = None) -> str:
    """What a driver on this machine uses: `HTMPC_BRIDGE_TOKEN`, else the token file (checked as above)."""
    environ = os.environ if environ is None else environ
    if environ.get(TOKEN_ENV):
        return _checked(environ[TOKEN_ENV], TOKEN_ENV)
    path = token_file or default_token_file()
    if not path.exists():
        raise ValueError(f"no bridge token: set {TOKEN_ENV} or create {path} (mode 0600); the studio writes it "
                         "on its first start with --backend bridge")
    return read_token_file(path)


def unauthorized(detail: str = "missing or wrong bearer token") -> HTTPException:
    """The 401 every protected route answers without the token."""
    return HTTPException(status.HTTP_401_UNAUTHORIZED, detail=detail, headers={"WWW-Authenticate": "Bearer"})


def require_token(request: Request,
                  credentials: Annotated[HTTPAuthorizationCredentials | None, Depends(BEARER)]) -> None:
    """FastAPI dependency of every mutating route: 401 unless the bearer token is right."""
    token: Token = request.app.state.token
    if credentials is None or not token.matches(credentials.credentials):
        raise unauthorized()
