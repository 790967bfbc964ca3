"""Paper II, Faraji et al., *Push recovery with stepping strategy based on time-projection
control* (``coman_lab``; ``coman`` for ablations), declared as a plugin (:data:`PLUGIN`).

- :mod:`.threelp`: the 3LP walking model, its closed-form propagation (Eqs. 1-6) and the
  step-to-step coordinates S, M, M̂, O (Eqs. 3, 7-8, 11);
- :mod:`.gait`: the periodic 3LP gait for a commanded speed (Eqs. 9-10);
- :mod:`.dlqr`: the step-to-step error map and the landing-constrained DLQR (Eqs. 11-14, 17);
- :mod:`.projection`: time projection (Eqs. 15-18) as look-up tables of torque and footstep
  gains over the phase (Fig. 13);
- :mod:`.controller` (registered as ``timeprojection``) with :mod:`.estimation`,
  :mod:`.openloop`, :mod:`.ik` and :mod:`.lift` around them, and :mod:`.joints` (the leg
  vector and the joints it names, found by name in the robot model at reset);
- :mod:`.metrics` and :mod:`.figures`: the paper's metrics and figures, from the log;
  :mod:`.plots`: its key signals, for viewers of a run.

The pure-math modules know nothing about MuJoCo or a particular robot: model parameters come
in through :class:`~.threelp.ThreeLPParams`.
"""

from walkrepro.plugins import Paper, Plugin

PLUGIN = Plugin(
    papers=(
        Paper(
            key="faraji",
            citation="Faraji et al., Push recovery with stepping strategy based on time-projection control",
            label="Paper II — Faraji et al., time-projection push recovery (`coman_lab`)",
            title="Faraji et al.",
            order=2,
            headline=("push_recovery_forward", "fig16_push"),
        ),
    ),
    controllers={"timeprojection": "walkrepro.papers.faraji.controller:TimeProjectionController"},
    metric_modules=("walkrepro.papers.faraji.metrics",),
    figures={"faraji": "walkrepro.papers.faraji.figures"},
    plots={"timeprojection": "walkrepro.papers.faraji.plots:PLOTS"},
)
