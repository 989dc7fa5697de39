"""Error against run time of the pillar-creep integrators (tactilepipe.papillarray.viscoelastic).

For every integrator (exponential, implicit Euler, RK4, forward Euler), PapillArray sample rate
(100/250/500/1000 Hz) and number of substeps, the reading of one pillar under a test load (the
lift's 0.6-s grip ramp, then a 20-ms load step) is compared with a reference solution on a
1-us grid, and one lift's worth of channels (2 sensors x 9 pillars x 3 axes) is timed.

Writes results/stability/integrators.{csv,md} (tactilepipe.core.tables.write_table) and
results/stability/integrators.png. The material is a soft silicone by default (two Prony modes:
5 % at 0.5 ms - far below every sample period, so the system is stiff - and 5 % at 1.5 s); the
simulators' own default has no creep until a measured curve exists (params.yaml).

Usage: python benchmarks/bench_integrators.py [--fractions 0.05 0.05] [--taus 0.0005 1.5]
       [--out results/stability] [--quick]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from tactilepipe.core.atomic import save_figure
from tactilepipe.core.plotting import close, figure
from tactilepipe.core.tables import write_table
from tactilepipe.papillarray import viscoelastic as ve

REPO = Path(__file__).resolve().parents[1]
COLOURS = {"exponential": "#4C72B0", "implicit_euler": "#55A868", "rk4": "#C44E52", "euler": "#8172B2"}
MARKERS = {100: "s", 250: "^", 500: "o", 1000: "D"}


def plot(table, prony: ve.Prony, out: Path) -> None:
    fig, axes = figure(9.0, 3.6, ncols=2)
    finite = table[~table["diverged"]]
    ceiling = 10 ** np.ceil(np.log10(max(finite["max_error_n"].max(), 1e-12)) + 1)
    for (method, rate), part in table.groupby(["method", "rate_hz"], sort=False):
        err = part["max_error_n"].where(~part["diverged"], ceiling)
        for ax, x in zip(axes, (part["step_ms"], part["loop_ms"])):
            ax.plot(x, err, "-", color=COLOURS[method], lw=0.8, alpha=0.6)
            ok = ~part["diverged"]
            ax.plot(x[ok], err[ok], MARKERS[rate], color=COLOURS[method], ms=4, ls="none")
            ax.plot(x[~ok], err[~ok], "x", color=COLOURS[method], ms=6, ls="none")
    for method, colour in COLOURS.items():
        axes[0].plot([], [], "-", color=colour, label=method)
    for rate, marker in MARKERS.items():
        axes[0].plot([], [], marker, color="k", ms=4, ls="none", label=f"{rate} Hz")
    axes[0].plot([], [], "x", color="k", ls="none", label="diverged (drawn at top)")
    for ax in axes:
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.axhline(ceiling, color="k", lw=0.5, ls=":")
        ax.set_ylabel("max |reading - reference| (N)")
    axes[0].set_xlabel("integrator step (ms)")
    axes[1].set_xlabel("run time per lift, 54 channels stepped in Python (ms)")
    axes[0].legend(fontsize=7, ncols=2)
    fast = min(prony.taus_s)
    fig.suptitle(f"Pillar creep integrators vs a 1-us reference (fastest mode {fast * 1e3:g} ms)")
    save_figure(out, fig)
    close(fig)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fractions", type=float, nargs="+", default=[0.05, 0.05])
    ap.add_argument("--taus", type=float, nargs="+", default=[0.0005, 1.5])
    ap.add_argument("--out", type=Path, default=REPO / "results" / "stability")
    ap.add_argument("--quick", action="store_true", help="500 Hz only, fewer substeps (for a check)")
    args = ap.parse_args(argv)
    prony = ve.Prony.from_params({"creep_fractions": args.fractions, "creep_tau_s": args.taus})
    t0 = time.perf_counter()
    kw = {"rates_hz": (500,), "substeps": (1, 2, 8), "repeats": 1} if args.quick else {}
    table = ve.benchmark(prony, **kw)
    limits = {m: ve.stability_limit_s(prony, m) for m in ve.METHODS}
    title = (f"Pillar creep integrators: error against run time (Prony g = {list(prony.fractions)}, "
             f"tau = {list(prony.taus_s)} s; reference: exponential integrator on a 1-us grid; "
             f"stability limits: Euler {limits['euler'] * 1e3:.3g} ms, RK4 {limits['rk4'] * 1e3:.3g} ms)")
    write_table(table, args.out / "integrators", title, "{:.3g}")
    plot(table, prony, args.out / "integrators.png")
    print((args.out / "integrators.md").read_text())
    print(f"written {args.out}/integrators.{{csv,md,png}} in {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()
