"""Type stub: pinocchio's bindings are compiled and ship no stubs pyright can read, so its names are Any."""

from typing import Any

def __getattr__(name: str) -> Any: ...
