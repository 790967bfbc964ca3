"""A minimal walkrepro plugin: one controller (``joint_pd``) and one metric (``pelvis_sag``).

walkrepro finds this object through the entry point in ``pyproject.toml``. The targets are
strings, so listing experiments imports nothing of this package beyond this file.
"""

from walkrepro.plugins import Plugin

PLUGIN = Plugin(
    controllers={"joint_pd": "walkrepro_example.controller:JointPdController"},
    metric_modules=("walkrepro_example.metrics",),
)
