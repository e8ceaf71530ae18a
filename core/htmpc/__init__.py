"""Perceptive hierarchical-task MPC: tasks, collision constraints (EDF / CBF), the lexicographic solve."""

from core.htmpc.htmpc import HTMPC

__all__ = ["HTMPC"]
