"""Paper III, Jo & Oh, *Impedance control of humanoid walking on uneven terrain with
centroidal momentum dynamics using QP* (``kist_humanoid``), declared as a plugin
(:data:`PLUGIN`).

Modules: :mod:`.footsteps` (footstep plan, ZMP reference, swing trajectory),
:mod:`.preview` (LIPM CoM–ZMP preview control, the paper's ref. [23]), :mod:`.tasks` (the
impedance modification, Eqs. 1–3, and the tasks of §III-D declared by name,
:class:`~.tasks.TaskSpec`, stacked each tick by :func:`~.tasks.stack_tasks`),
:mod:`.centroidal_qp` (the QP of §III-D, built, solved through ``qpsolvers`` (``daqp`` by
default, ξ̈ eliminated) or by the opt-in ``active_set``, and Eq. 9), :mod:`.condensed` (the
opt-in ``active_set`` solver), :mod:`.controller` (registered as ``qpimpedance``; its task
list is :func:`~.controller.paper_tasks`), :mod:`.metrics` and :mod:`.figures` (the paper's
metrics and figures, from the log), :mod:`.plots` (its key signals, for viewers of a run).
"""

from walkrepro.plugins import Paper, Plugin

PLUGIN = Plugin(
    papers=(
        Paper(
            key="jo_oh",
            citation="Jo & Oh, Impedance control of humanoid walking on uneven terrain with CMD and QP",
            label="Paper III — Jo & Oh, impedance control on uneven terrain (`kist_humanoid`)",
            title="Jo & Oh",
            order=3,
            headline=(
                "obstacle_4cm",
                "fig4_contact_force_obstacle_4cm_vs_obstacle_4cm_no_impedance",
            ),
        ),
    ),
    controllers={"qpimpedance": "walkrepro.papers.jo_oh.controller:QPImpedanceController"},
    metric_modules=("walkrepro.papers.jo_oh.metrics",),
    figures={"jo_oh": "walkrepro.papers.jo_oh.figures"},
    plots={"qpimpedance": "walkrepro.papers.jo_oh.plots:PLOTS"},
)
