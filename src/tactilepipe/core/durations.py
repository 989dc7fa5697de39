"""Durations as the compute estimate prints them (pipeline/estimate.py, tool/estimate.py)."""

from __future__ import annotations


def hours_text(hours: float) -> str:
    """Minutes below a tenth of an hour, else hours."""
    if hours < 0.1:
        return f"{hours * 60:.1f} min"
    return f"{hours:,.1f} h"
