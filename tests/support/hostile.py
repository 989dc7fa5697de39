"""Inputs written to exhaust a reader rather than to record anything: what the bounds must refuse."""

from __future__ import annotations


def billion_laughs(levels: int = 9) -> str:
    """A YAML file of a few hundred bytes standing for 9**levels strings: each anchor's list repeats
    the one before it 9 times."""
    lines = ['l0: &l0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    lines += [f"l{i}: &l{i} [{', '.join([f'*l{i - 1}'] * 9)}]" for i in range(1, levels)]
    return "\n".join(lines) + "\n"
