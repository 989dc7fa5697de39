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
       [--out results/stability] [--quick] [--small]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd

from tactilepipe.core.atomic import save_figure
from tactilepipe.core.plotting import close, figure
from tactilepipe.core.tables import write_table
from tactilepipe.papillarray import viscoelastic as ve

REPO = Path(__file__).resolve().parents[1]
COLOURS = {"exponential": "#4C72B0", "implicit_euler": "#55A868", "rk4": "#C44E52", "euler": "#8172B2"}
MARKERS = {100: "s", 250: "^", 500: "o", 1000: "D"}


def benchmark_load(t: np.ndarray, grip_n: float = 2.0, tap_n: float = 1.0) -> np.ndarray:
    """Test load of one pillar (N): the gripper closes over 0.6 s (the lift simulator's grip ramp),
    then a 20-ms minimum-jerk load step (a quick tap / weight set down) at 1.5 s, held."""
    def mj(x):
        x = np.clip(x, 0.0, 1.0)
        return 10 * x**3 - 15 * x**4 + 6 * x**5
    return grip_n * mj((t - 0.3) / 0.6) + tap_n * mj((t - 1.5) / 0.02)


def reference_reading(prony: ve.Prony, duration_s: float, h_ref: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
    """(t, reading) of ``benchmark_load`` by the exponential integrator on a 1-us grid (the load
    evaluated exactly there; its linear interpolation error is below 1e-8 N at this step)."""
    n = int(round(duration_s / h_ref)) + 1
    t = np.arange(n) * h_ref
    return t, ve.integrate(benchmark_load(t), h_ref, prony, "exponential")


def explicit_step(prony: ve.Prony, h: float, method: str, s: np.ndarray, f0: np.ndarray, f1: np.ndarray) -> np.ndarray:
    """One literal step of an explicit method, stage by stage: s (C, m), f (C,)."""
    a, b = prony.system()

    def rhs(state, f):
        return state @ a.T + f[:, None] * b[None, :]
    if method == "euler":
        return s + h * rhs(s, f0)
    fm = 0.5 * (f0 + f1)
    k1 = rhs(s, f0)
    k2 = rhs(s + h / 2 * k1, fm)
    k3 = rhs(s + h / 2 * k2, fm)
    k4 = rhs(s + h * k3, f1)
    return s + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)


def stepped_reading(force: np.ndarray, dt: float, prony: ve.Prony, method: str, substeps: int) -> np.ndarray:
    """The reference loop: the reading ``ve.integrate`` computes, stepped in Python one substep at a
    time (the explicit methods stage by stage, the others by their step matrices)."""
    f = np.asarray(force, np.float64).reshape(len(force), -1)
    h = dt / substeps
    g = np.asarray(prony.fractions, float)
    phi, g0, g1 = ve.step_matrices(prony, h, method)
    s = np.zeros((f.shape[1], len(g)))
    out = np.empty_like(f)
    out[0] = prony.g_inf * f[0]
    with np.errstate(over="ignore", invalid="ignore"):
        for n in range(len(f) - 1):
            fa, fb = f[n], f[n + 1]
            for k in range(substeps):
                lo = fa + (fb - fa) * (k / substeps)
                hi = fa + (fb - fa) * ((k + 1) / substeps)
                if method in ("euler", "rk4"):
                    s = explicit_step(prony, h, method, s, lo, hi)
                else:
                    s = s @ phi.T + lo[:, None] * g0[None, :] + hi[:, None] * g1[None, :]
            out[n + 1] = prony.g_inf * fb + s @ g
    return out.reshape(np.shape(force))


def error_table(prony: ve.Prony, rates_hz=(100, 250, 500, 1000), substeps=(1, 2, 4, 8, 16),
              duration_s: float = 3.0, channels: int = 54, repeats: int = 3, methods=ve.METHODS):
    """Error against run time of every integrator and step size, against the fine-step reference.

    Per (method, sample rate, substeps): max and RMS |reading - reference| at the samples (N; the
    reference solves the continuous load, so this includes the error of knowing the load only at
    the samples), ``integration_error_n``: max error against the exact solution for the sampled
    load taken linear between samples (the integrator's own error; the exponential integrator's is
    round-off), whether the step is within the method's stability limit, whether it diverged, and the wall time
    of one simulated lift's worth of channels (``channels`` pillar axes over ``duration_s``) stepped
    in Python (``loop_ms``, ``stepped_reading``: every method timed the same way) and by the
    simulator's modal recursion (``modal_ms``), and the largest difference between the two
    readings (``loop_vs_modal_n``; they compute the same recursion). Returns a pandas DataFrame.
    """
    t_ref, r_ref = reference_reading(prony, duration_s)
    h_ref = t_ref[1] - t_ref[0]
    rows = []
    for rate in rates_hz:
        dt = 1.0 / rate
        n = int(round(duration_s * rate)) + 1
        t = np.arange(n) * dt
        ref = r_ref[np.rint(t / h_ref).astype(np.int64)]
        load = benchmark_load(t)
        many = np.repeat(load[:, None], channels, axis=1)
        exact = ve.integrate(load, dt, prony, "exponential", 1)
        for method in methods:
            limit = ve.stability_limit_s(prony, method)
            for k in substeps:
                reading = ve.integrate(load, dt, prony, method, k, check_stability=False)
                err = np.abs(reading - ref)
                diverged = (not np.isfinite(err).all()) or err.max() > 1e3 * np.abs(load).max()
                timings, outputs = {}, {}
                for name, run in (("loop_ms", lambda x: stepped_reading(x, dt, prony, method, k)),
                                  ("modal_ms", lambda x: ve.integrate(x, dt, prony, method, k, check_stability=False))):
                    run(many[:3])                       # warm-up
                    best = np.inf
                    for _ in range(repeats):
                        t0 = time.perf_counter()
                        outputs[name] = run(many)
                        best = min(best, time.perf_counter() - t0)
                        if best > 1.0:
                            break
                    timings[name] = best * 1e3
                stepped = outputs["loop_ms"][:, 0]      # every channel carries ``load``
                rows.append({"method": method, "rate_hz": int(rate), "substeps": int(k),
                             "step_ms": dt / k * 1e3, "within_stability_limit": bool(dt / k <= limit),
                             "diverged": bool(diverged),
                             "max_error_n": float("inf") if diverged else float(err.max()),
                             "rms_error_n": float("inf") if diverged else float(np.sqrt(np.mean(err**2))),
                             "integration_error_n": float("inf") if diverged
                             else float(np.abs(reading - exact).max()),
                             "loop_vs_modal_n": float("nan") if diverged else float(np.abs(stepped - reading).max()),
                             **timings})
    return pd.DataFrame(rows)


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
    ap.add_argument("--out", type=Path, default=None, help="default: results/stability (--small: a temporary folder)")
    ap.add_argument("--quick", action="store_true", help="500 Hz only, fewer substeps (for a check)")
    ap.add_argument("--small", action="store_true", help="--quick with two integrators and one timing run, "
                    "written to a temporary folder unless --out is given: a check that it runs")
    args = ap.parse_args(argv)
    if args.small:
        return _small(args)
    args.out = args.out or REPO / "results" / "stability"
    prony = ve.Prony.from_params({"creep_fractions": args.fractions, "creep_tau_s": args.taus})
    t0 = time.perf_counter()
    kw = {"rates_hz": (500,), "substeps": (1, 2, 8), "repeats": 1} if args.quick else {}
    table = error_table(prony, **kw)
    limits = {m: ve.stability_limit_s(prony, m) for m in ve.METHODS}
    title = (f"Pillar creep integrators: error against run time (Prony g = {list(prony.fractions)}, "
             f"tau = {list(prony.taus_s)} s; reference: exponential integrator on a 1-us grid; "
             f"stability limits: Euler {limits['euler'] * 1e3:.3g} ms, RK4 {limits['rk4'] * 1e3:.3g} ms)")
    write_table(table, args.out / "integrators", title, "{:.3g}")
    plot(table, prony, args.out / "integrators.png")
    print((args.out / "integrators.md").read_text())
    print(f"written {args.out}/integrators.{{csv,md,png}} in {time.perf_counter() - t0:.1f} s")


def _small(args) -> None:
    import tempfile
    with tempfile.TemporaryDirectory(prefix="tactilepipe-bench-integrators-") as tmp:
        out = args.out or Path(tmp)
        prony = ve.Prony.from_params({"creep_fractions": args.fractions, "creep_tau_s": args.taus})
        table = error_table(prony, rates_hz=(500,), substeps=(1, 2), repeats=1, methods=("exponential", "euler"))
        write_table(table, out / "integrators", "Pillar creep integrators (small check)", "{:.3g}")
        plot(table, prony, out / "integrators.png")
        print((out / "integrators.md").read_text())


if __name__ == "__main__":
    main()
