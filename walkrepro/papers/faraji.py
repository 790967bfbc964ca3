"""Paper II, Faraji et al., *Push recovery with stepping strategy based on time-projection
control*: the 3LP time-projection controller (``timeprojection``), its metrics and figures."""

from walkrepro.plugins import Plugin

PLUGIN = Plugin(
    controllers={
        "timeprojection": "walkrepro.controllers.timeprojection.controller:TimeProjectionController"
    },
    metric_modules=("walkrepro.paper_metrics.faraji",),
    figures={"faraji": "walkrepro.figures.faraji"},
)
