"""A run shown from its log and metrics: the figures (registry, overview, style), the
declared signal plots, snapshot strips and video rendered headless, the Rerun
export.
"""
