"""Recordings of a run: snapshots to MCAP and back (`recorder.py`, topics and schemas in `topics.py`), the
studio's replay of a file (`replay.py`) and the report of a headless run (`report.py`, imported on its own:
it loads the plotting library)."""

from app.recording.recorder import Recorder, Recording, read_recording
from app.recording.replay import ReplaySource, wait_until_played

__all__ = ["Recorder", "Recording", "ReplaySource", "read_recording", "wait_until_played"]
