"""Paper II (Faraji et al., time-projection push recovery): the pure-math core.

- :mod:`.threelp`: the 3LP walking model, its closed-form propagation (Eqs. 1-6) and the
  step-to-step coordinates S, M, M̂, O (Eqs. 3, 7-8, 11);
- :mod:`.gait`: the periodic 3LP gait for a commanded speed (Eqs. 9-10);
- :mod:`.dlqr`: the step-to-step error map and the landing-constrained DLQR (Eqs. 11-14, 17);
- :mod:`.projection`: time projection (Eqs. 15-18) as look-up tables of torque and footstep
  gains over the phase (Fig. 13).

Nothing here knows about MuJoCo or a particular robot: model parameters come in through
:class:`~.threelp.ThreeLPParams`.
"""
