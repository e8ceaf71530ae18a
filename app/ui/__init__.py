"""The studio's browser UI (viser). It reads runtime snapshots only (docs/design.md)."""
