"""Paper III, Jo & Oh, *Impedance control of humanoid walking on uneven terrain with
centroidal momentum dynamics using QP*: the centroidal QP with foot impedance
(``qpimpedance``), its metrics and figures."""

from walkrepro.plugins import Plugin

PLUGIN = Plugin(
    controllers={
        "qpimpedance": "walkrepro.controllers.qpimpedance.controller:QPImpedanceController"
    },
    metric_modules=("walkrepro.paper_metrics.jo_oh",),
    figures={"jo_oh": "walkrepro.figures.jo_oh"},
)
