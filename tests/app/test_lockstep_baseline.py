"""No behaviour change: a lockstep run of the default scene on the object map gives the committed baseline
(`tests/app/lockstep_baseline.py`: mapped objects, removals, the final q to 6 decimals, every plan's task
errors and status). A refactoring must pass this unchanged; an intended change of behaviour regenerates
the file with `python -m tests.app.lockstep_baseline --write` and says so in its commit."""

import json

import numpy as np

from tests.app.lockstep_baseline import BASELINE, run_summary

ROUNDING = 2e-6
"""Values are stored to 6 decimals: two roundings apart at most."""
"""Lockstep runs are bit-identical from process to process (the object registration is single-threaded and
no cache is keyed by an object's address), so everything is compared to the stored rounding."""


def test_a_lockstep_run_matches_the_baseline():
    expected = json.loads(BASELINE.read_text(encoding="utf-8"))
    got = json.loads(json.dumps(run_summary()))
    assert got.keys() == expected.keys()
    for key in ("duration_s", "run_state", "removed", "plan_status"):
        assert got[key] == expected[key], key
    assert len(got["objects"]) == len(expected["objects"])
    for mine, theirs in zip(got["objects"], expected["objects"], strict=True):
        assert mine["status"] == theirs["status"]
        np.testing.assert_allclose(mine["position"] + mine["extent"], theirs["position"] + theirs["extent"],
                                   atol=ROUNDING)
    np.testing.assert_allclose(got["t_end"], expected["t_end"], atol=ROUNDING)
    np.testing.assert_allclose(got["q_final"], expected["q_final"], atol=ROUNDING)
    np.testing.assert_allclose(np.array(got["task_errors"]), np.array(expected["task_errors"]), atol=ROUNDING)
