"""Which recording sessions the simulator wrote. The workflow names each simulated session
``sim-<name>`` (``sim-<scale>`` for a build's embedded data); a lab names its own sessions
anything else. A data set may hold both, and its QC then says so: a score over simulated and
recorded trials together describes neither."""

from __future__ import annotations

from collections.abc import Iterable

SIMULATED_PREFIX = "sim-"


def is_simulated(session: str) -> bool:
    """A session the simulator writes, not one recorded on a rig."""
    return session.startswith(SIMULATED_PREFIX)


def mixed_data_note(sessions: Iterable[str], unit: str) -> str | None:
    """A sentence for a QC page when ``sessions`` (one entry per ``unit``: trial, lift) mix
    simulated and recorded sessions; None when they do not."""
    sessions = list(sessions)
    flags = [is_simulated(s) for s in sessions]
    sim = sorted({s for s, f in zip(sessions, flags) if f})
    real = sorted({s for s, f in zip(sessions, flags) if not f})
    if not sim or not real:
        return None
    n_sim = sum(flags)
    return (f"Mixed data: {n_sim} {unit}(s) from simulated session(s) ({', '.join(sim)}) and "
            f"{len(sessions) - n_sim} from recorded session(s) ({', '.join(real)}): its scores describe neither "
            f"alone. Build a lab's sessions on their own (a build of their own in params.yaml) to score them.")
