"""Read and write task sequences as YAML; a bad file raises `FileFormatError` naming field and line."""

from __future__ import annotations

from pathlib import Path

import yaml

from core.atomic_file import write_text_atomic
from core.yaml_validation import FileFormatError, load_yaml_file, load_yaml_model
from tasks.schema import TaskSequence

EXAMPLES_DIR = Path(__file__).parent / "examples"

__all__ = ["EXAMPLES_DIR", "FileFormatError", "load_sequence", "parse_sequence", "save_sequence", "sequence_to_yaml"]


def load_sequence(path: str | Path) -> TaskSequence:
    """Load a sequence file; nothing is returned unless the whole file is valid."""
    return load_yaml_file(path, TaskSequence)


def parse_sequence(text: str, source: str = "<sequence>") -> TaskSequence:
    """Parse sequence YAML text (an upload, a bridge request)."""
    return load_yaml_model(text, TaskSequence, source)


_KEY_ORDER = ("name", "kind", "target", "waypoints", "ee", "tolerance", "timeout_s", "dwell_s", "priority")


_PLACE_KEYS = ("x", "y", "yaw_deg", "position", "rpy_deg")


def _drop_world_frame(pose):
    """`frame: world` is the default: written only when it says something; an anchored pose is its anchor."""
    if isinstance(pose, dict) and pose.get("anchor") is not None:
        return {k: v for k, v in pose.items() if k not in (*_PLACE_KEYS, "frame")}
    if isinstance(pose, dict) and pose.get("frame") == "world":
        return {k: v for k, v in pose.items() if k != "frame"}
    if isinstance(pose, list):
        return [_drop_world_frame(p) for p in pose]
    return pose


def sequence_to_yaml(seq: TaskSequence) -> str:
    """YAML text of a sequence (subtask keys in reading order); `parse_sequence` reads it back equal."""
    data = seq.model_dump(mode="json", exclude_none=True)
    data["subtasks"] = [{k: _drop_world_frame(s[k]) for k in _KEY_ORDER if k in s and s[k] != []}
                        for s in data["subtasks"]]
    return yaml.safe_dump(data, sort_keys=False, default_flow_style=None)


def save_sequence(seq: TaskSequence, path: str | Path) -> None:
    """Write a sequence file."""
    write_text_atomic(path, sequence_to_yaml(seq))
