"""Metrics specific to the jo_oh reproduction (computed from the log alone)."""

from __future__ import annotations
