"""The drift scene's scores.json as `tactilepipe diff` reads it (pipeline/diff.py): the fits are
made deterministically, so every number is a single value; no draws."""

from __future__ import annotations

MODEL_STAGES = {"drift-report"}     # stages whose change leaves the recordings' reading alone
SINGLE_SKIP: set[str] = set()


def scored_keys(node: dict) -> set[str]:
    return set()


def scored_series(metrics: dict) -> dict:
    return {}


def draws_shown_same(old: dict, new: dict) -> set[str]:
    return set()


def test_train_ratio(run: dict) -> float:
    return float(run["metrics"].get("test_train_ratio", 0.0) or 0.0)


def current_layout(metrics: dict) -> dict:
    return metrics
