import numpy as np

from app.ui.monitor_panel import _finite


def test_plot_series_have_no_nan():
    """viser's uPlot draws nothing at all when a series holds one NaN."""
    np.testing.assert_array_equal(_finite([np.nan, np.nan, 1.0, np.nan, 3.0, np.nan]), [0, 0, 1, 1, 3, 3])
    np.testing.assert_array_equal(_finite([np.nan] * 3), [0, 0, 0])
    np.testing.assert_array_equal(_finite([1.0, 2.0]), [1.0, 2.0])


def test_run_history_keeps_the_whole_run_thinned_beyond_the_window():
    from app.ui.monitor_panel import RunHistory

    history = RunHistory(window=100, older_max=200)
    for k in range(10_000):
        history.append((float(k),))
    t = [row[0] for row in history.rows()]
    assert t[0] == 0.0 and t[-1] == 9999.0  # from the start of the run to now
    assert t[-100:] == [float(k) for k in range(9900, 10_000)]  # the window at full rate
    assert len(history) <= 300 and np.all(np.diff(t) > 0)


def test_the_legend_names_objects_by_map_id_and_a_new_run_starts_over(robot):
    import viser

    from app.runtime.snapshot import RunState, Snapshot
    from app.ui.monitor_panel import MonitorPanel
    from core.params import MappingParams
    from core.types import MappedObject, ObjectMapSnapshot, RobotState
    from tests.app.conftest import free_port

    def snap(t, ids, run_state=RunState.RUNNING):
        objects = tuple(MappedObject(i, np.eye(4), np.ones(3), np.zeros((0, 3)), MappingParams().prior()) for i in ids)
        return Snapshot(seq=0, wall_time=0.0, state=RobotState(t, np.zeros(9), np.zeros(9)), run_state=run_state,
                        object_map=ObjectMapSnapshot(t, objects))

    server = viser.ViserServer(port=free_port())
    try:
        monitor = MonitorPanel(server)
        monitor.build_plots()
        monitor.update(snap(0.0, [], RunState.IDLE))
        for k in range(1, 2000):
            monitor.update(snap(0.05 * k, [7, 3] if k > 10 else [7]))
        assert monitor.object_labels()[:3] == ["#7", "#3", "—"]
        assert monitor.rows[0][0] == 0.05 and monitor.rows[-1][0] == 0.05 * 1999  # the whole run since Start
        monitor._plot()
        assert monitor.consistency is not None
        assert [s["label"] for s in monitor.consistency.series][1:3] == ["#7", "#3"]
        monitor.update(snap(100.0, [7], RunState.FINISHED))
        monitor.update(snap(100.1, [9]))  # Start again
        assert len(monitor.rows) == 1 and monitor.object_labels()[0] == "#9"
    finally:
        server.stop()
