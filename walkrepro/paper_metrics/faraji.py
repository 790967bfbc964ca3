"""Metrics specific to the faraji reproduction (computed from the log alone)."""

from __future__ import annotations
