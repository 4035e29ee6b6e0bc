"""
The envelope of ``rigid-body-sim plot`` without scipy: numpy's running extremes and mean.

recording/plot.py drew a fast oscillation's envelope with scipy.ndimage's
maximum_filter1d, minimum_filter1d and uniform_filter1d (mode='reflect'); it now computes
them with numpy, so that the run-time venv needs no scipy for plotting.  These tests hold
the numpy versions to scipy's results, double for double, on random data (scipy is in the
test set, requirements-test.txt).
"""

import ast
from pathlib import Path

import numpy as np
import pytest
from rigid_body_sim.recording import plot
from scipy.ndimage import maximum_filter1d
from scipy.ndimage import minimum_filter1d
from scipy.ndimage import uniform_filter1d


def _cases(seed, count, longest):
    """Yield (values, window): random lengths, windows up to twice the length, scales."""
    rng = np.random.default_rng(seed)
    for _ in range(count):
        length = int(rng.integers(1, longest + 1))
        window = int(rng.integers(1, 2 * length + 3))
        scale = 10.0 ** rng.uniform(-6.0, 6.0)
        yield rng.normal(size=length) * scale + rng.normal() * scale, window


@pytest.mark.parametrize('seed', [0, 1, 2])
def test_running_extremes_equal_scipys_maximum_and_minimum_filters(seed):
    """Every window length, shorter or longer than the series: the very same doubles."""
    for values, window in _cases(seed, 400, 300):
        np.testing.assert_array_equal(plot._running_extreme(values, window, np.maximum),
                                      maximum_filter1d(values, window, mode='reflect'))
        np.testing.assert_array_equal(plot._running_extreme(values, window, np.minimum),
                                      minimum_filter1d(values, window, mode='reflect'))


@pytest.mark.parametrize('seed', [0, 1, 2])
def test_running_mean_equals_scipys_uniform_filter_double_for_double(seed):
    """The same running sum as scipy's, so not merely close: equal."""
    for values, window in _cases(seed, 400, 300):
        np.testing.assert_array_equal(plot._running_mean(values, window),
                                      uniform_filter1d(values, window, mode='reflect'))


def test_filters_equal_scipys_on_a_long_oscillation_as_the_plot_draws_it():
    """
    A long record and the plot's own window (three mean periods), on a column of omega.

    The column is a strided view, as ``omega[:, k]`` in the plot; 160 cycles over 200,000
    samples take a window of 3,739 samples (the numpy versions are O(n), not O(n window)).
    """
    rng = np.random.default_rng(3)
    time = np.linspace(0.0, 100.0, 200_000)
    omega = np.stack([np.sin(2.0 * np.pi * 2.0 * time) + 0.01 * time,
                      rng.normal(size=time.size), np.cos(time)], axis=1)
    values = omega[:, 0]
    cycles = plot.oscillations(values)
    assert cycles > plot._ENVELOPE_CYCLES
    window = int(np.ceil(3.0 * len(values) / cycles))
    for column in omega.T:
        np.testing.assert_array_equal(plot._running_extreme(column, window, np.maximum),
                                      maximum_filter1d(column, window, mode='reflect'))
        np.testing.assert_array_equal(plot._running_extreme(column, window, np.minimum),
                                      minimum_filter1d(column, window, mode='reflect'))
        np.testing.assert_array_equal(plot._running_mean(column, window),
                                      uniform_filter1d(column, window, mode='reflect'))


def test_a_fast_oscillation_is_drawn_as_its_envelope_and_running_mean():
    """The plot's own path (_draw_series): the shaded band between the running extremes."""
    from matplotlib.figure import Figure  # no pyplot: the backend stays as it is

    time = np.linspace(0.0, 10.0, 20_001)
    values = np.sin(2.0 * np.pi * 10.0 * time) + 0.2 * np.sin(2.0 * np.pi * 0.1 * time)
    axes = Figure().subplots()
    line = plot._draw_series(axes, time, values, 'tab:red', 'omega_x')
    assert 'envelope shaded' in line.get_label()
    window = int(np.ceil(3.0 * len(values) / plot.oscillations(values)))
    # The mean line: the running mean at the picked samples, where its window is whole.
    mean = uniform_filter1d(values, window, mode='reflect')
    picked = np.searchsorted(time, line.get_xdata())
    np.testing.assert_array_equal(line.get_ydata(), mean[picked])
    # The band's edges: the running maximum and minimum (the two thin lines drawn first).
    lower, upper = axes.get_lines()[:2]
    picked = np.searchsorted(time, upper.get_xdata())
    np.testing.assert_array_equal(upper.get_ydata(),
                                  maximum_filter1d(values, window, mode='reflect')[picked])
    np.testing.assert_array_equal(lower.get_ydata(),
                                  minimum_filter1d(values, window, mode='reflect')[picked])


def test_plot_module_imports_no_scipy():
    """The run-time set has no scipy: plot.py must not import it, even lazily."""
    tree = ast.parse(Path(plot.__file__).read_text())
    imported = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            imported.update(alias.name.split('.')[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            imported.add(node.module.split('.')[0])
    assert 'scipy' not in imported
