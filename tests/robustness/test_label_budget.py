"""Every kept label within the budget of the truth (docs/robustness.md, "The label error budget").

The simulator knows the force at every instant: simulated sessions with legitimate variations
(light presses, slow ramps, stiff gels, mixed camera rates) must keep every trial within the
budget; a fault injected into one trial must leave it out with its cause named, or leave its
labels within the budget; the session's other trials stay kept and within it. The faulty trial
and the data set go through the real command line. A seeded subset at a small size; the whole
draw is benchmarks/bench_label_budget.py.
"""

from __future__ import annotations

import re

import pytest

from support import label_faults as fault
from support import label_harness as harness
from support import witness_faults as chain_fault
from tactilepipe.tool.formats.native_layout import read_calibration

pytestmark = pytest.mark.slow

VICTIM = "screwdriver_1_p01_normal01"      # a 19-N press: a fault has force to show
OTHER = "screwdriver_1_p00_normal01"


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    root = tmp_path_factory.mktemp("budget")
    base = harness.session(root / "clean" / "lab", harness.parameters())
    result = harness.run_case(base, root / "case", {}, via_cli=True)
    return {"base": base, "result": result, "root": root,
            "shards": {n: root / "case" / "shards" / f"{n}.parquet" for n in base.trials}}


def _all_kept_within_budget(result: dict, skip: str | None = None) -> None:
    for name, r in result.items():
        if name == skip:
            continue
        assert r["status"] == "kept", (name, r)
        assert r["over"] is None, (name, r["over"])


def test_a_clean_session_keeps_every_trial_within_the_budget(clean):
    assert len(clean["result"]) == 9
    _all_kept_within_budget(clean["result"])
    # the budget has room: clean labels use under half of it (so a fault has to be real to break it)
    worst = max(r["error"]["mae"] / harness.budget(r["error"]["peak"])["mae"] for r in clean["result"].values())
    assert worst < 0.5, worst


@pytest.mark.parametrize("variation", sorted(harness.VARIATIONS))
def test_a_legitimate_variation_keeps_every_trial_within_the_budget(tmp_path, variation):
    overrides = harness.VARIATIONS[variation]
    base = harness.session(tmp_path / "raw" / "lab", harness.parameters(overrides))
    result = harness.run_case(base, tmp_path / "case", overrides, via_cli=True)
    assert len(result) == 9
    _all_kept_within_budget(result)


def test_a_session_mixing_30_and_60_fps_trials_keeps_every_trial(tmp_path):
    base = harness.session(tmp_path / "raw" / "lab", harness.parameters(),
                           rate_of=lambda spec: 60.0 if spec.trial_index == 1 else 30.0)
    result = harness.run_case(base, tmp_path / "case", {}, via_cli=True)
    assert len(result) == 9
    _all_kept_within_budget(result)


def _cal(base):
    return read_calibration(base.folder / "nano17.cal")


# name: (fault(trial folder, base session), the cause a trial left out must name)
FAULTS = {
    "zero offset +1 N": (lambda t, b: chain_fault.zero_offset(t, _cal(b), 1.0), "witness 'rest at both ends'"),
    "zero offset -1 N": (lambda t, b: chain_fault.zero_offset(t, _cal(b), -1.0), "witness 'rest at both ends'"),
    "zero drifting +1 N within the trial": (lambda t, b: fault.drift(t, _cal(b), 1.0), "witness 'zero drift'"),
    "zero drifting -1 N within the trial": (lambda t, b: fault.drift(t, _cal(b), -1.0), "witness 'zero drift'"),
    "arrival stamps 0.2 s late": (lambda t, b: fault.arrivals_late(t, 0.2), "witness 'clock'"),
    "arrival stamps 0.4 s late": (lambda t, b: fault.arrivals_late(t, 0.4), "witness 'clock'"),
    "port-open stamp 0.2 s late, no arrival stamps": (lambda t, b: fault.port_open_late(t, 0.2), None),
    "port-open stamp 0.3 s late, no arrival stamps": (lambda t, b: fault.port_open_late(t, 0.3), None),
    "port-open stamp 0.4 s late, no arrival stamps": (lambda t, b: fault.port_open_late(t, 0.4), None),
    "another trial's samples": (lambda t, b: fault.samples_of(t, t.parent / OTHER), "witness '(clock|images)'"),
    "open gauge wire": (lambda t, b: fault.open_gauge(t, 2), "witness 'gauge wire'"),
    "exposure step on one camera": (lambda t, b: fault.exposure_step(t, "digit_left", 1.4), "witness 'exposure'"),
    "exposure step on both cameras": (lambda t, b: fault.exposure_step_on_both(t, 1.4), "witness 'exposure'"),
    "every second frame repeated": (lambda t, b: fault.repeated_frames(t), None),
    "cameras swapped": (lambda t, b: fault.swap_cameras(t), None),      # no label changes: docs/robustness.md
    "one camera for both fingers": (lambda t, b: fault.one_camera_twice(t), "hold one camera's frames"),
}
# Faults the witnesses do not catch yet, each a measured overrun (docs/robustness.md lists them):
# the test fails the day one is caught, so the list stays true.
KNOWN_OVERRUNS = {
    "gauge gain x3": lambda t, b: chain_fault.gauge_gain(t, 3.0),
    "gauge gain x1.5": lambda t, b: chain_fault.gauge_gain(t, 1.5),
    "gauge gain x0.5": lambda t, b: chain_fault.gauge_gain(t, 0.5),
    "gauge gain x0.33": lambda t, b: chain_fault.gauge_gain(t, 0.33),
    "arrival stamps 50 ms late": lambda t, b: fault.arrivals_late(t, 0.05),
    "arrival stamps 0.1 s late": lambda t, b: fault.arrivals_late(t, 0.1),
}


@pytest.mark.parametrize("name", sorted(FAULTS))
def test_a_fault_is_left_out_with_its_cause_or_stays_within_the_budget(clean, tmp_path, name):
    inject, cause = FAULTS[name]
    result = harness.run_case(clean["base"], tmp_path, {}, lambda t: inject(t, clean["base"]), VICTIM,
                              via_cli=True, shards=clean["shards"])
    _all_kept_within_budget(result, skip=VICTIM)
    victim = result[VICTIM]
    if victim["status"] == "kept":
        assert victim["over"] is None, f"{name}: kept over the budget: {victim['over']}"
        assert cause is None, f"{name}: kept (within the budget), the witness meant to name it did not"
    else:
        assert cause is not None and re.search(cause, victim["reason"]), (name, victim)


@pytest.mark.parametrize("name", sorted(KNOWN_OVERRUNS))
def test_a_known_overrun_is_still_an_overrun(clean, tmp_path, name):
    result = harness.run_case(clean["base"], tmp_path, {}, lambda t: KNOWN_OVERRUNS[name](t, clean["base"]), VICTIM,
                              via_cli=True, shards=clean["shards"])
    assert result[VICTIM]["status"] == "kept" and result[VICTIM]["over"], result[VICTIM]
