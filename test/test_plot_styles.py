"""Every method in a benchmark plot is told apart: a (colour, marker) pair of its own."""

from pathlib import Path

from matplotlib.colors import to_rgba
import matplotlib.pyplot as plt
import pytest

from rigid_body_sim.work_precision.forces_report import forces_figure
from rigid_body_sim.work_precision.report import method_styles
from rigid_body_sim.work_precision.report import read_results
from rigid_body_sim.work_precision.report import work_precision_figure
from rigid_body_sim.work_precision.tolerance_report import tolerance_figure

BENCHMARK = Path(__file__).resolve().parent.parent / 'docs' / 'benchmark'


def _style(line):
    """Return a drawn line's (colour as RGBA, marker), how a reader tells methods apart."""
    return to_rgba(line.get_color()), line.get_marker()


def _legend_styles(figure):
    """Return {label: style} of the method entries of the figure's legends."""
    legends = list(figure.legends) + [axis.get_legend() for axis in figure.axes
                                      if axis.get_legend() is not None]
    styles = {}
    for legend in legends:
        for handle, text in zip(legend.legend_handles, legend.get_texts()):
            marker = handle.get_marker() if hasattr(handle, 'get_marker') else None
            if marker not in ('x', 'None', None, ''):
                styles[text.get_text()] = _style(handle)
    return styles


def _drawn_styles(figure):
    """Return the set of styles of the data lines (not the 'x' of untracked points)."""
    return {_style(line) for axis in figure.axes for line in axis.get_lines()
            if line.get_marker() not in ('x', 'None', None, '') and len(line.get_xdata())}


def _figures():
    results = read_results(BENCHMARK / 'results.json')
    forces = read_results(BENCHMARK / 'forces.json')
    sweep = read_results(BENCHMARK / 'tolerance_sweep.json')
    yield 'work_precision', results['methods'], lambda: work_precision_figure(results)
    yield 'work_precision_long', results['methods'], \
        lambda: work_precision_figure(results, 'long')
    yield 'forces', sorted({r['method'] for r in forces['records']}), \
        lambda: forces_figure(forces)
    yield 'tolerance_sweep', sorted({r['method'] for r in sweep['records']}), \
        lambda: tolerance_figure(sweep)


@pytest.mark.parametrize('name, methods, make', list(_figures()),
                         ids=[name for name, _, _ in _figures()])
def test_each_method_of_a_committed_benchmark_plot_has_a_style_of_its_own(name, methods,
                                                                          make):
    """
    The legend names every method once, with as many distinct (colour, marker) as methods.

    The forces plot once drew its 11 methods on a 10-colour cycle with one marker for all of
    ours: buss and splitting4 were the same blue circles.  Every drawn line wears one of
    the legend's styles, so no curve goes unnamed.
    """
    figure = make()
    try:
        legend = _legend_styles(figure)
        assert len(legend) == len(methods), (sorted(legend), methods)
        assert len(set(legend.values())) == len(methods), legend
        assert _drawn_styles(figure) <= set(legend.values())
    finally:
        plt.close(figure)


def test_method_styles_stay_distinct_for_many_methods():
    """Ninety of our methods and twelve of MuJoCo's still get a pair each."""
    methods = [f'method{k}' for k in range(90)] + [f'mujoco_{k}' for k in range(12)]
    styles = method_styles(methods)
    pairs = {(to_rgba(s['color']), s['marker']) for s in styles.values()}
    assert len(pairs) == len(methods)
    with pytest.raises(ValueError, match='91 methods to draw'):
        method_styles([f'method{k}' for k in range(91)])
