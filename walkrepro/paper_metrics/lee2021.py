"""Metrics specific to the lee2021 reproduction (computed from the log alone)."""

from __future__ import annotations
