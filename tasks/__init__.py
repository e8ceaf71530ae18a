"""Task sequences: the schema of subtasks, YAML files, the sequencer and base path planning."""

from tasks.schema import BasePose, BaseSubtask, EEPose, EESubtask, Subtask, TaskSequence, Tolerance
from tasks.sequence_file import load_sequence, parse_sequence, save_sequence, sequence_to_yaml

__all__ = ["BasePose", "BaseSubtask", "EEPose", "EESubtask", "Subtask", "TaskSequence", "Tolerance",
           "load_sequence", "parse_sequence", "save_sequence", "sequence_to_yaml"]
