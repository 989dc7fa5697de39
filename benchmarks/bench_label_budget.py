"""The label error budget over the whole draw: simulated sessions (one tool, 3 poses x 3 presses),
clean and legitimately varied, and every fault family at several sizes injected into pressing
trials; each kept trial's labels against the simulator's truth (tests/support/label_harness.py).

Prints, per family and size, on how many trials the fault was caught (left out or refused with a
reason), kept within the budget (it did not reach the labels), or kept over it (an overrun: a
failure nobody named); then the clean and varied sessions' trials left out (false alarms) and
overruns; and the run time. The seeded subset of this draw runs in the test suite
(tests/robustness/test_label_budget.py); benchmarks/record.md keeps its tables, docs/robustness.md
the outcome per fault.

Usage: python benchmarks/bench_label_budget.py [--seeds 2] [--victims 3] [--families ...] [--small]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests"))

from support import label_faults as fault  # noqa: E402
from support import label_harness as harness  # noqa: E402
from support import witness_faults as chain_fault  # noqa: E402
from tactilepipe.tool.formats.native_layout import read_calibration  # noqa: E402


def families(base) -> dict[str, tuple[list, callable]]:
    cal = read_calibration(base.folder / "nano17.cal")
    return {
        "gauge gain x": ([0.33, 0.5, 0.67, 0.8, 1.25, 1.5, 2.0, 3.0], lambda t, m: chain_fault.gauge_gain(t, m)),
        "zero offset N": ([-2.0, -1.0, -0.5, 0.5, 1.0, 2.0], lambda t, m: chain_fault.zero_offset(t, cal, m)),
        "zero drift N": ([-1.0, -0.5, 0.5, 1.0, 2.0], lambda t, m: fault.drift(t, cal, m)),
        "arrival stamps late s": ([0.02, 0.05, 0.1, 0.15, 0.2, 0.4], lambda t, m: fault.arrivals_late(t, m)),
        "port-open late s (no arrivals)": ([0.1, 0.3, 0.6], lambda t, m: fault.port_open_late(t, m)),
        "exposure step x": ([1.05, 1.1, 1.2, 1.4], lambda t, m: fault.exposure_step(t, "digit_left", m)),
        "exposure step on both cameras x": ([1.1, 1.4], lambda t, m: fault.exposure_step_on_both(t, m)),
        "open gauge wire": ([2], lambda t, m: fault.open_gauge(t, m)),
        "another trial's samples": ([0], None),
        "cameras swapped": ([0], lambda t, m: fault.swap_cameras(t)),
        "one camera twice": ([0], lambda t, m: fault.one_camera_twice(t)),
        "every second frame repeated": ([0], lambda t, m: fault.repeated_frames(t)),
    }


def outcome(result: dict, victim: str) -> str:
    r = result[victim]
    if r["status"] != "kept":
        return "caught"
    return "overrun" if r["over"] else "within"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--victims", type=int, default=3)
    ap.add_argument("--families", nargs="*", help="only these fault families (default: all)")
    ap.add_argument("--no-variations", action="store_true", help="only the clean session, no varied ones")
    ap.add_argument("--small", action="store_true", help="one seed, one victim, one family: a check that it runs")
    args = ap.parse_args()
    if args.small:
        args.seeds, args.victims, args.families, args.no_variations = 1, 1, ["zero offset N"], True
    start = time.perf_counter()
    table: dict[tuple[str, float], Counter] = {}
    alarms, reasons = Counter(), Counter()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for seed in range(args.seeds):
            params = harness.parameters(seed=seed)
            base = harness.session(tmp / f"s{seed}" / "lab", params)
            clean = harness.run_case(base, tmp / f"s{seed}-clean", {})
            shards = {n: tmp / f"s{seed}-clean" / "shards" / f"{n}.parquet" for n in base.trials}
            for name, result in [("clean", clean)] + [
                    (v, harness.run_case(harness.session(tmp / f"s{seed}-{i}" / "lab", harness.parameters(o, seed=seed)),
                                         tmp / f"s{seed}-{i}-case", o))
                    for i, (v, o) in enumerate(harness.VARIATIONS.items()) if not args.no_variations]:
                alarms[(name, "trials")] += len(result)
                alarms[(name, "left out")] += sum(r["status"] != "kept" for r in result.values())
                alarms[(name, "overrun")] += sum(bool(r.get("over")) for r in result.values())
                reasons.update(f"{name}: {r['reason'][:90]}" for r in result.values() if r["status"] != "kept")
            names = list(base.trials)
            victims = names[1::max(1, len(names) // args.victims)][:args.victims]
            for family, (sizes, inject) in families(base).items():
                if args.families and family not in args.families:
                    continue
                for size in sizes:
                    for k, victim in enumerate(victims):
                        if inject is None:              # another trial's samples: the next trial's
                            other = names[(names.index(victim) + 1) % len(names)]
                            apply = (lambda t, o=other: fault.samples_of(t, t.parent / o))
                        else:
                            apply = (lambda t, m=size, f=inject: f(t, m))
                        work = tmp / f"s{seed}-{family}-{size}-{k}".replace(" ", "_").replace("'", "")
                        result = harness.run_case(base, work, {}, apply, victim, shards=shards)
                        table.setdefault((family, size), Counter())[outcome(result, victim)] += 1
                        others = {n: r for n, r in result.items() if n != victim}
                        alarms[("others of a faulty session", "trials")] += len(others)
                        alarms[("others of a faulty session", "left out")] += sum(r["status"] != "kept"
                                                                                  for r in others.values())
                        alarms[("others of a faulty session", "overrun")] += sum(bool(r.get("over"))
                                                                                 for r in others.values())
                        reasons.update(f"others ({family} {size}): {r['reason'][:90]}" for r in others.values()
                                       if r["status"] != "kept")
    print(f"{'fault':34s} {'size':>6s}  caught  within  overrun   (of {args.seeds * args.victims} trials)")
    for (family, size), c in table.items():
        print(f"{family:34s} {size:>6g}  {c['caught']:6d}  {c['within']:6d}  {c['overrun']:7d}")
    print(f"\n{'session':28s} trials  left out  overrun")
    for name in dict.fromkeys(k[0] for k in alarms):
        print(f"{name:28s} {alarms[(name, 'trials')]:6d}  {alarms[(name, 'left out')]:8d}  {alarms[(name, 'overrun')]:7d}")
    if reasons:
        print("\nwhy the clean trials left out were left out:")
        for why, n in reasons.most_common():
            print(f"  {n:3d}  {why}")
    print(f"\nrun time {time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main()
