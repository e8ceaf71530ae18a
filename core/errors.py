"""The root of the project's own errors, and the "not possible here" error every layer shares.

Every error the project raises on purpose derives from `StudioError` and also from the standard-library base
its callers already catch (`ValueError` for bad input, `RuntimeError` for "not possible now",
`FileNotFoundError`, `ConnectionError`): `except StudioError` catches the project's errors and nothing else,
and `except ValueError` keeps working. docs/design.md ("Errors") lists the public ones.
"""

from __future__ import annotations


class StudioError(Exception):
    """Root of every error Perceptive HTMPC Studio raises on purpose."""


class NotSupportedError(StudioError, RuntimeError):
    """This runtime or backend cannot do what was asked (the message says what it would need)."""
