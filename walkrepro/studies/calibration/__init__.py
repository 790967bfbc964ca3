"""Declared calibration (TARGETS.md, Calibration; docs/calibration.md).

A paper's own statement about its set-up, or an identification procedure it describes, may
pin a model parameter that no source gives. ``experiments/calibration/<paper>.yaml`` declares
each such parameter (:mod:`walkrepro.specs.calibration_files`); specs refer to its committed value by name
(:mod:`walkrepro.specs.calibrated`); the rules between the file and the specs are checked (:mod:`.rules`);
``walkrepro calibrate`` searches the value on the sweep engine (:mod:`.search`, :mod:`.run`).
"""
