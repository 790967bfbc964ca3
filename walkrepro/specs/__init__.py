"""What an experiment is: the spec's data model (:mod:`~walkrepro.specs.models`, the leaf),
its files found by name and loaded with overrides and calibration
(:mod:`~walkrepro.specs.files`), YAML with file:line errors, known deviations, the
provenance classes of its fields, the ``sweeps:`` section's models, and the declared
calibration files (``experiments/calibration/<paper>.yaml``) that its ``calibrated``
values come from. Nothing here needs the simulation: checking a spec against what is
installed is :mod:`walkrepro.runs.resolve`.
"""
