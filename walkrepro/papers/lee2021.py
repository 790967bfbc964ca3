"""Paper I, Lee et al., *Toward Reactive Walking*: the E-FSM whole-body controller (``efsm``),
its metrics and its figures."""

from walkrepro.plugins import Plugin

PLUGIN = Plugin(
    controllers={"efsm": "walkrepro.controllers.efsm.controller:EfsmController"},
    metric_modules=("walkrepro.paper_metrics.lee2021",),
    figures={"lee2021": "walkrepro.figures.lee2021"},
)
