"""A bag is one whole lift (volume/whole_lift.py; docs/robustness.md, "Volume labels"): simulated
lifts recorded two in one bag, or cut so the bag starts after lift-off or ends before the put-down,
are refused by `tactilepipe volume-dataset` with that cause named, after `tactilepipe
papillarray-ingest` took their bags; a short bump, a dip of the load in the air and clean lifts of
varied volumes, rates and timings are kept."""

from __future__ import annotations

import json
import re

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tactilepipe.cli import main as cli
from tactilepipe.core.config import load_params
from tactilepipe.volume import simulate as vsim

from support.bags import write_ros1_bag
from support.project import REPO
from support.volume_data import write_lifts_bag

SMOKE = load_params(REPO / "params.yaml", {"scale": "smoke"})
SIM = SMOKE["simulate_volume"]
START_NS = vsim.lift_start_ns(vsim.Lift("x", 0.0, "main", 0, 0), SIM)
SPAN = r"(\d+\.\d\d)-(\d+\.\d\d) s"


def simulated(volume: float, index: int, **sim) -> dict:
    return vsim.simulate_lift(vsim.Lift(f"v{int(volume):03d}_main_l{index:02d}", volume, "main", 0, index),
                              {**SIM, **sim}, SMOKE["seed"])


@pytest.fixture(scope="module")
def lifts():
    """Smoke-scale lifts of 300 ml and of the empty container (56 g, the lightest load)."""
    return {(v, i): simulated(v, i) for v in (0.0, 300.0) for i in (1, 2)}


def volume_dataset(tmp_path, bags: dict, method: str = "auto") -> int:
    """Write ``bags`` ({name: (volume_ml, recs, keep_s)}) into a session, ingest them with
    `tactilepipe papillarray-ingest` and run `tactilepipe volume-dataset` on it."""
    raw, shards = tmp_path / "raw" / "s", tmp_path / "shards" / "s"
    pairs = []
    for name, (_, recs, keep_s) in bags.items():
        write_lifts_bag(raw / f"{name}.bag", recs, START_NS, write_ros1_bag, keep_s)
        pairs += [str(raw / f"{name}.bag"), str(shards / f"{name}.parquet")]
    assert cli.main(["papillarray-ingest", "--params", str(REPO / "params.yaml"), *pairs]) == 0
    (raw / "lifts.csv").write_text("bag,volume_ml,set\n" + "".join(f"{n}.bag,{v:g},main\n" for n, (v, _, _) in
                                                                   bags.items()))
    override = {"volume_sessions": ["s"], "segment": {"method": method}}
    return cli.main(["volume-dataset", "--params", str(REPO / "params.yaml"), "--scale", "smoke",
                     "--override", json.dumps(override), "--raw-root", str(tmp_path / "raw"),
                     "--shard-root", str(tmp_path / "shards"), "--out", str(tmp_path / "dataset.parquet"),
                     "--qc", str(tmp_path / "qc.csv")])


def refusal(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    return err


@pytest.mark.parametrize("method", ["auto", "force"])
@pytest.mark.parametrize("volume", [0.0, 300.0])
def test_two_lifts_in_one_bag_are_refused_naming_both(lifts, tmp_path, capsys, method, volume):
    """Lifted, put down, lifted again: today the first lift would be kept and the second dropped."""
    first, second = lifts[(volume, 1)], lifts[(volume, 2)]
    assert volume_dataset(tmp_path, {"twice": (volume, [first, second], (0.0, None))}, method) == 2
    err = refusal(capsys)
    m = re.search(rf"twice\.parquet: two lifts in one bag: off the table at {SPAN} and {SPAN} \(by the "
                  rf"{'pose' if method == 'auto' else 'force'} method", err)
    assert m, err
    # each phase lies in its own lift's off-table time (the second lift starts where the first ends)
    offset = first["t"][-1] + first["t"][1]
    for (a, b), rec, shift in [(m.group(1, 2), first, 0.0), (m.group(3, 4), second, offset)]:
        lifted = rec["t"][rec["off_table"]] + shift
        assert lifted[0] - 0.3 <= float(a) < float(b) <= lifted[-1] + 0.3, (a, b, lifted[[0, -1]])
    assert not (tmp_path / "qc.csv").exists()


@pytest.mark.parametrize("method", ["auto", "force"])
@pytest.mark.parametrize("cut_s", [1.4, 3.0])            # during the rise, during the hold
def test_a_bag_that_starts_after_lift_off_is_refused_naming_it(lifts, tmp_path, capsys, method, cut_s):
    rec = lifts[(300.0, 1)]
    assert rec["off_table"][rec["t"] < cut_s].any()          # the container left the table before the cut
    assert volume_dataset(tmp_path, {"late": (300.0, [rec], (cut_s, None))}, method) == 2
    err = refusal(capsys)
    m = re.search(r"late\.parquet: the bag starts after lift-off: the sensors already carry up to (\d\.\d+) N of "
                  r"vertical shear \(\|Fy0\| \+ \|Fy1\|\) over its first 0\.20 s, where its rest level is read, "
                  r"(\d\.\d+) N more than over its last", err)
    assert m, err
    assert 3.2 < float(m[2]) < 3.8 and "never leaves the table" not in err     # 356 g: 3.49 N


def test_a_bag_must_hold_its_rest_level_before_the_pads_take_the_load(lifts, tmp_path, capsys):
    """The rest level is read over the first 2 x segment.force_smooth_s: a bag that starts 0.1 s
    before the pads take the load is refused as above (its rest would hold part of the load); one
    that starts 0.4 s before is kept, and carries what the whole recording carries (within half
    volume_checks.label_floor_n)."""
    rec = lifts[(300.0, 1)]
    onset = rec["t"][np.argmax(rec["true_force"][..., 1].sum(axis=(1, 2)) > 0.01)]
    bags = {"whole": (300.0, [rec], (0.0, None)), "early_enough": (300.0, [rec], (onset - 0.4, None))}
    assert volume_dataset(tmp_path, bags) == 0
    qc = pd.read_csv(tmp_path / "qc.csv").set_index("lift")
    assert qc.loc["s/early_enough", "carried_n"] == pytest.approx(qc.loc["s/whole", "carried_n"], abs=0.05)
    capsys.readouterr()
    assert volume_dataset(tmp_path / "late", {"late": (300.0, [rec], (onset - 0.1, None))}) == 2
    assert "late.parquet: the bag starts after lift-off: the sensors already carry up to" in refusal(capsys)


@pytest.mark.parametrize("method", ["auto", "force"])
def test_a_bag_that_ends_before_the_put_down_is_refused_naming_it(lifts, tmp_path, capsys, method):
    rec = lifts[(0.0, 1)]
    cut_s = rec["phases"]["hold"][1]                          # stopped at the end of the hold
    assert volume_dataset(tmp_path, {"early": (0.0, [rec], (0.0, cut_s))}, method) == 2
    err = refusal(capsys)
    m = re.search(r"early\.parquet: the bag ends before the container is put down: over its last 0\.20 s the sensors "
                  r"still carry (\d\.\d+) N of vertical shear above their level over its first, of the (\d\.\d+) "
                  r"N carried off the table", err)
    assert m, err
    assert 0.4 < float(m[1]) < 0.7 and 0.4 < float(m[2]) < 0.7                 # 56 g: 0.55 N


def test_a_lift_that_never_leaves_the_table_keeps_its_message(tmp_path, capsys):
    # 0.1 mm of arm travel stretches the pads by 2.2 N: the 356-g container stays on the table
    rec = simulated(300.0, 1, lift_height_m=1e-4)
    assert not rec["off_table"].any()
    assert volume_dataset(tmp_path, {"stays": (300.0, [rec], (0.0, None))}) == 2
    err = refusal(capsys)
    assert re.search(r"stays\.parquet: the lift never leaves the table \(longest off-table phase", err), err
    assert "lift-off" not in err and "two lifts" not in err


@pytest.mark.parametrize("method", ["auto", "force"])
def test_a_short_bump_or_a_dip_in_the_air_is_one_lift(lifts, tmp_path, method):
    """A bump (lifted 1 cm for about half a second, put down) before or after a lift, and a lift
    whose load dips to 60 % for 0.5 s in the hold (a re-grip), are kept, each as its one lift. (By
    the force method the dip splits the hold, and the longer part is kept as the off-table phase.)"""
    bump = simulated(300.0, 3, lift_duration_s=0.3, hold_duration_s=0.2, lift_height_m=0.01)
    assert 0.1 < np.ptp(bump["t"][bump["off_table"]]) < SMOKE["segment"]["min_off_table_s"]
    lift = lifts[(300.0, 1)]
    dipped = {**lift, "force": lift["force"].copy()}
    hold = lift["phases"]["hold"]
    dip = (lift["t"] >= hold[0] + 0.45) & (lift["t"] < hold[0] + 0.95)
    dipped["force"][dip, :, :, 1] *= 0.6
    bags = {"bump_lift": (300.0, [bump, lift], (0.0, None)), "lift_bump": (300.0, [lift, bump], (0.0, None)),
            "dipped": (300.0, [dipped], (0.0, None))}
    assert volume_dataset(tmp_path, bags, method) == 0
    qc = pd.read_csv(tmp_path / "qc.csv").set_index("lift")
    assert set(qc.index) == {f"s/{name}" for name in bags}
    assert (qc.loc[["s/bump_lift", "s/lift_bump"], "off_table_s"] > 3.0).all(), qc["off_table_s"]  # not the bump
    assert qc.loc["s/bump_lift", "off_table_s"] == pytest.approx(qc.loc["s/lift_bump", "off_table_s"], abs=0.05)


@settings(max_examples=4, derandomize=True, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(rate_hz=st.sampled_from([100, 250, 500]), lift_s=st.floats(0.8, 2.5), hold_s=st.floats(1.0, 3.0),
       volumes=st.lists(st.sampled_from([0.0, 25.0, 75.0, 150.0, 225.0, 300.0]), min_size=3, max_size=3),
       index=st.integers(0, 13))
def test_clean_lifts_of_varied_volumes_rates_and_timings_are_kept(tmp_path_factory, rate_hz, lift_s, hold_s,
                                                                  volumes, index):
    """No false alarm: each clean lift is kept, by the pose and by the force method."""
    sim = {"rate_hz": rate_hz, "lift_duration_s": lift_s, "hold_duration_s": hold_s}
    bags = {f"l{k}": (v, [simulated(v, index + k, **sim)], (0.0, None)) for k, v in enumerate(volumes)}
    for method in ("auto", "force"):
        tmp = tmp_path_factory.mktemp("clean")
        assert volume_dataset(tmp, bags, method) == 0, method
        kept = set(pd.read_parquet(tmp / "dataset.parquet", columns=["lift"])["lift"])
        assert kept == {f"s/{name}" for name in bags}, method
