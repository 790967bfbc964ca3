"""A minimal walkrepro plugin: its paper (``example``), one controller (``joint_pd``) and one
metric (``pelvis_sag``).

walkrepro finds this object through the entry point in ``pyproject.toml``. The targets are
strings, so listing experiments imports nothing of this package beyond this file. The
package's own specs (``experiments/``) name the paper by its key, ``paper: {key: example}``.
"""

from walkrepro.plugins import Paper, Plugin

PLUGIN = Plugin(
    papers=(
        Paper(
            key="example",
            citation="walkrepro's example plugin: a joint PD controller stands (no paper)",
            label="Example — a joint PD controller stands (`dyros_red`)",
            title="Example",
        ),
    ),
    controllers={"joint_pd": "walkrepro_example.controller:JointPdController"},
    metric_modules=("walkrepro_example.metrics",),
)
