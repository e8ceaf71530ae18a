"""Task sequences: the schema of subtasks, YAML files, the sequencer, base path planning and target checks.

`Sequencer(robot, sequence).update(state, occupied_points, t)` turns the active subtask into the controller's
`References` every control period (None: nothing left to do); `check_sequence` checks targets before a run.
"""

from tasks.path_planner import NoPathError, plan_path
from tasks.schema import BasePose, BaseSubtask, EEPose, EESubtask, Subtask, TaskSequence, Tolerance
from tasks.sequence_file import load_sequence, parse_sequence, save_sequence, sequence_to_yaml
from tasks.sequencer import Outcome, Sequencer, SubtaskProgress
from tasks.validation import TargetError, check_sequence

__all__ = ["BasePose", "BaseSubtask", "EEPose", "EESubtask", "NoPathError", "Outcome", "Sequencer", "Subtask",
           "SubtaskProgress", "TargetError", "TaskSequence", "Tolerance", "check_sequence", "load_sequence",
           "parse_sequence", "plan_path", "save_sequence", "sequence_to_yaml"]
