"""A run judged from its log alone: metrics (the registry and the core metrics) and the
paper's checks (expectations to verdicts). Named ``evaluation`` because
:func:`walkrepro.evaluate` is the library's function.
"""
