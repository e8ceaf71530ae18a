import numpy as np

from app.ui.monitor_panel import _finite


def test_plot_series_have_no_nan():
    """viser's uPlot draws nothing at all when a series holds one NaN."""
    np.testing.assert_array_equal(_finite([np.nan, np.nan, 1.0, np.nan, 3.0, np.nan]), [0, 0, 1, 1, 3, 3])
    np.testing.assert_array_equal(_finite([np.nan] * 3), [0, 0, 0])
    np.testing.assert_array_equal(_finite([1.0, 2.0]), [1.0, 2.0])
