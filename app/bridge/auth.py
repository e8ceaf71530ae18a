"""The bridge's bearer token: where it comes from, and the checks that require it.

Order: an explicit token (configuration, `BridgeServer(token=...)`), else `HTMPC_BRIDGE_TOKEN` from
the environment, else the user's token file (`$XDG_CONFIG_HOME/htmpc-studio/bridge_token`, by default
`~/.config/...`), else a new random token, saved there (mode 0600) and printed once. The robot link
and every request that changes anything need `Authorization: Bearer <token>`; a missing or wrong
token is answered with 401.
"""

from __future__ import annotations

import logging
import os
import secrets
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

from fastapi import Depends, HTTPException, Request, status
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer

log = logging.getLogger(__name__)

TOKEN_ENV = "HTMPC_BRIDGE_TOKEN"
MIN_TOKEN_CHARS = 16
BEARER = HTTPBearer(auto_error=False, description="the bridge token (see docs/bridge.md, 'Auth')")
"""Declares the scheme in the OpenAPI schema; the check itself is `require_token`."""


def default_token_file() -> Path:
    """`$XDG_CONFIG_HOME/htmpc-studio/bridge_token` (XDG default `~/.config`)."""
    base = os.environ.get("XDG_CONFIG_HOME") or str(Path.home() / ".config")
    return Path(base) / "htmpc-studio" / "bridge_token"


@dataclass(frozen=True)
class Token:
    """The token and where it came from ('config', 'environment', 'file' or 'generated')."""

    value: str
    source: str
    path: Path | None = None

    def matches(self, credentials: str | None) -> bool:
        """Whether `credentials` is this token (constant-time comparison)."""
        return bool(credentials) and secrets.compare_digest(credentials.strip().encode(), self.value.encode())

    def matches_header(self, authorization: str | None) -> bool:
        """Whether an `Authorization` header value is 'Bearer <this token>'."""
        scheme, _, credentials = (authorization or "").strip().partition(" ")
        return scheme.lower() == "bearer" and self.matches(credentials)


def _checked(value: str, source: str) -> str:
    value = value.strip()
    if len(value) < MIN_TOKEN_CHARS or any(c.isspace() for c in value):
        raise ValueError(f"bridge token from {source} must be at least {MIN_TOKEN_CHARS} characters, no spaces")
    return value


def _generate(path: Path) -> Token:
    value = secrets.token_hex(24)  # hex: a generated token never starts with "-" (argparse takes that for an option)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(fd, "w", encoding="utf-8") as f:
        f.write(value + "\n")
    print(f"hardware bridge: generated a new token, saved in {path}: {value}", flush=True)
    return Token(value, "generated", path)


def resolve_token(explicit: str | None = None, token_file: Path | None = None,
                  environ: dict[str, str] | None = None) -> Token:
    """The token by the order above; generates and saves one on first run."""
    environ = os.environ if environ is None else environ
    if explicit:
        return Token(_checked(explicit, "configuration"), "config")
    if environ.get(TOKEN_ENV):
        return Token(_checked(environ[TOKEN_ENV], TOKEN_ENV), "environment")
    path = token_file or default_token_file()
    if path.exists():
        return Token(_checked(path.read_text(encoding="utf-8"), str(path)), "file", path)
    return _generate(path)


def read_token(explicit: str | None = None, token_file: Path | None = None) -> str:
    """What a driver on this machine uses: the explicit token, the environment, else the token file."""
    if explicit:
        return explicit
    if os.environ.get(TOKEN_ENV):
        return os.environ[TOKEN_ENV]
    path = token_file or default_token_file()
    try:
        return path.read_text(encoding="utf-8").strip()
    except OSError as err:
        raise ValueError(f"no bridge token: pass --token, set {TOKEN_ENV} or create {path}") from err


def unauthorized(detail: str = "missing or wrong bearer token") -> HTTPException:
    """The 401 every protected route answers without the token."""
    return HTTPException(status.HTTP_401_UNAUTHORIZED, detail=detail, headers={"WWW-Authenticate": "Bearer"})


def require_token(request: Request,
                  credentials: Annotated[HTTPAuthorizationCredentials | None, Depends(BEARER)]) -> None:
    """FastAPI dependency of every mutating route: 401 unless the bearer token is right."""
    token: Token = request.app.state.token
    if credentials is None or not token.matches(credentials.credentials):
        raise unauthorized()
