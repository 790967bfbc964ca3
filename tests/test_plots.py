"""The plots each controller declares (``Plugin.plots``): every line names a value its
controller logs, in a unit."""

from __future__ import annotations

import pytest

from walkrepro import plugins
from walkrepro.log.record import TOPIC_SIGNALS, TOPIC_STATE
from walkrepro.present.plots import Plot, Series, signal_plots


def _signal_layouts() -> dict:
    """Each of walkrepro's controllers with declared plots -> its signal layout."""
    from walkrepro.papers.faraji.controller import SIGNAL_LAYOUT as faraji
    from walkrepro.papers.jo_oh.controller import SIGNAL_LAYOUT as jo_oh
    from walkrepro.papers.lee2021.controller import signal_layout

    return {"efsm": signal_layout(12), "timeprojection": faraji, "qpimpedance": jo_oh}


def test_every_paper_controller_declares_its_plots() -> None:
    """Paper I, II and III's controllers each declare plots, with distinct keys and units."""
    declared = plugins.plot_declarations()
    assert {"efsm", "timeprojection", "qpimpedance"} <= declared.keys()
    for target in declared.values():
        plots = plugins.load(target)
        assert plots and all(isinstance(p, Plot) and p.unit and p.series for p in plots)
        assert len({p.key for p in plots}) == len(plots)


@pytest.mark.parametrize("controller", ["efsm", "timeprojection", "qpimpedance"])
def test_every_declared_line_is_a_logged_value(controller: str) -> None:
    """Each line is a signal of the controller's layout (a scalar, or an entry inside an
    array) or a simulator state."""
    layout = _signal_layouts()[controller]
    for plot in plugins.load(plugins.plot_declarations()[controller]):
        for series in plot.series:
            if series.topic == TOPIC_STATE:
                assert series.field in ("qpos", "qvel") and series.index is not None
                continue
            assert series.topic == TOPIC_SIGNALS, series.path
            _, size, _ = layout.slots[series.field]
            assert (series.index is None) == (size == 0), series.path
            assert series.index is None or series.index < size, series.path


def test_a_series_path_is_checked_when_declared() -> None:
    """A path that is not /topic.field or /topic.field[i] is refused at once."""
    assert Series("/sim/state.qvel[0]", "v").index == 0
    with pytest.raises(ValueError, match="not /topic.field"):
        Series("controller.cp_w", "x")


def test_an_undeclared_controller_plots_its_scalar_signals() -> None:
    """A controller without declarations gets one plot of its scalar signals, unit ``?``."""
    (plot,) = signal_plots(["posture_error"])
    assert plot.name == "controller signals [?]"
    assert [s.path for s in plot.series] == [f"{TOPIC_SIGNALS}.posture_error"]
    assert signal_plots([]) == ()
