"""Paper-specific metrics, one module per paper, registered with :func:`walkrepro.metrics.metric`.

Each paper's plugin (:mod:`walkrepro.papers`) declares its module; :mod:`walkrepro.metrics`
imports them on the first metric lookup, so that spec validation knows every name.
"""
