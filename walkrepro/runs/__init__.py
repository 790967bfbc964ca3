"""A run: the loop that joins the simulation, the controller and the log
(:mod:`~walkrepro.runs.runner`), one experiment end to end from spec to verdict and
figures (:mod:`~walkrepro.runs.experiment`), and the run directories.
"""
