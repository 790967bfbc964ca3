"""Paper-specific metrics, one module per paper, registered with :func:`walkrepro.metrics.metric`.

They are imported by :mod:`walkrepro.metrics` so that spec validation knows every name.
"""
