"""Paper I, Lee et al., *Toward Reactive Walking* (``dyros_red``): event-based FSM walking
with an operational-space whole-body controller, declared as a plugin (:data:`PLUGIN`).

Modules: :mod:`.controller` (the controller registered as ``efsm``), :mod:`.fsm` (the
E-FSM: capture point, Eqs. 2–4, ε, Table I), :mod:`.wbc` (the OS-WBC: P, W, Φ, Λ, Ñ, the
task hierarchy of Eq. 11, Appendices A–D), :mod:`.kernels` (the compiled tick that runs
them, its records and its signals), :mod:`.metrics` (the paper's metrics, from the log),
:mod:`.figures` (its figures redrawn from a run) and :mod:`.plots` (its key signals, for
viewers of a run).
"""

from walkrepro.plugins import Paper, Plugin

PLUGIN = Plugin(
    papers=(
        Paper(
            key="lee2021",
            citation="Lee et al., Toward Reactive Walking (E-FSM + OS-WBC)",
            label="Paper I — Lee et al., Toward Reactive Walking (E-FSM, `dyros_red`)",
            title="Lee et al. 2021",
            order=1,
            headline=("forward_walk", "fig7_com_feet"),
        ),
    ),
    controllers={"efsm": "walkrepro.papers.lee2021.controller:EfsmController"},
    metric_modules=("walkrepro.papers.lee2021.metrics",),
    figures={"lee2021": "walkrepro.papers.lee2021.figures"},
    plots={"efsm": "walkrepro.papers.lee2021.plots:PLOTS"},
)
