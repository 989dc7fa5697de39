"""QC report and data figures of a tool dataset (before any model)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from tactilepipe.core.atomic import write_text
from tactilepipe.core.simulated import mixed_data_note
from tactilepipe.tool.report import figures_data as figures
from tactilepipe.tool.formats.trials import open_trial, trial_format
from tactilepipe.tool.formats.serial_log import SATURATED


def qc_markdown(qc: dict, label: str) -> str:
    rows = ["| trial | tool | frames L/R | pairs | dropped (reason: count) | clock shift found (s) | xcorr | "
            f"{label} force range (N) |", "|---|---|---|---|---|---|---|---|"]
    total_drops: dict[str, int] = {}
    for t in qc["trials"]:
        drops = {k: v for k, v in t["drops"].items() if v}
        for k, v in drops.items():
            total_drops[k] = total_drops.get(k, 0) + v
        clock = t["clock"]
        shift = clock.get("refined_shift_s", clock.get("offset_s", float("nan")))
        rows.append(f"| {t['trial']} | {t['tool']} | {t['frames'].get('digit_left', 0)}/"
                    f"{t['frames'].get('digit_right', 0)} | {t['pairs']} | "
                    f"{', '.join(f'{k}: {v}' for k, v in drops.items()) or '—'} | {shift:+.3f} | "
                    f"{clock.get('xcorr', float('nan')):.2f} | {t['force_min_n']:.2f} – {t['force_max_n']:.2f} |")
    head = [f"# QC: {qc['kind']} trials", "",
            f"{len(qc['trials'])} trials, {qc['pairs']} frame pairs at {qc['image_size']} px; "
            f"dropped in total: {total_drops or 'none'}.", ""]
    mixed = mixed_data_note([t["trial"].split("/")[0] for t in qc["trials"]], "trial")   # trial: <session>/<name>
    if mixed:
        head += [mixed, ""]
    sizes = sorted({f"{w}x{h}" for t in qc["trials"] for w, h in t.get("frame_size", {}).values()})
    if sizes:
        head += [f"Frames recorded at {', '.join(sizes)} (width x height), resized to {qc['image_size']} x "
                 f"{qc['image_size']} px: the aspect ratio is not kept.", ""]
    dropped = qc.get("dropped_trials", [])
    if dropped:
        head += [f"**Left out:** {len(dropped)} trial(s) whose labels cannot be trusted, each with its cause (a "
                 f"force clock not aligned to the cameras, a witness of its labels, or a trial standing out from "
                 f"its session: docs/robustness.md, \"Every label has a witness\"):", ""] + \
                [f"- {d['trial']} ({d['source']}): {d['reason']}" for d in dropped] + [""]
    fallback = [t["trial"] for t in qc["trials"] if t["clock"].get("fallback")]
    if fallback:
        head += [f"**Clock not refined:** {len(fallback)} trial(s) ({', '.join(fallback)}) keep the host clock "
                 f"(tool_ingest.clock.on_low_score: host_clock): their labels may be off by the Arduino's "
                 f"port-open offset (tenths of a second).", ""]
    saturated = {t["trial"]: sum(v for k, v in t["drops"].items() if k.endswith(SATURATED)) for t in qc["trials"]}
    saturated = {k: v for k, v in saturated.items() if v}
    if saturated:
        head += [f"**Nano17 saturated:** {sum(saturated.values())} force samples at the ADC rails (a gauge at "
                 f"count 0 or 1023: the force was beyond the sensor's range) in {len(saturated)} trial(s) "
                 f"({', '.join(saturated)}) were dropped: no label comes from a clipped reading, frame pairs among "
                 f"them are labelled from the unsaturated samples either side or dropped as 'force gap', "
                 f"so those presses' peak forces are under-represented.", ""]
    return "\n".join(head + rows) + "\n"


def build_data_report(data_dir: Path, out_dir: Path, label: str, level_n: float) -> None:
    qc = json.loads((data_dir / "qc.json").read_text())
    samples = pd.read_parquet(data_dir / "samples.parquet")
    write_text(out_dir / "qc.md", qc_markdown(qc, label))
    figs = out_dir / "figures"
    figures.force_histogram(samples[label].to_numpy(), label, figs / "force_histogram.png")
    figures.force_profiles(samples, label, level_n, figs / "force_profiles.png")

    # the trial with the strongest press shows the data best
    trial_index = int(samples.loc[samples[label].idxmax(), "trial_index"])
    one = samples[samples["trial_index"] == trial_index]
    frames = np.load(data_dir / "frames.npy", mmap_mode="r")
    refs = np.load(data_dir / "references.npy", mmap_mode="r")
    idx = one.index.to_numpy()
    rmse = np.stack([figures.tactile_rmse(frames[idx, s], refs[trial_index, s]) for s in range(2)], axis=1)
    name = one["trial"].iloc[0]
    figures.rmse_vs_force(one["t_s"].to_numpy(), rmse, one[label].to_numpy(), label,
                          f"{name}: tactile change vs reference frame", figs / "rmse_vs_force.png")
    source = Path(qc["trials"][trial_index]["source"]) if "source" in qc["trials"][trial_index] else None
    if source is not None and source.exists():
        raw = open_trial(source, trial_format(source))
        phases = figures.press_phases(one["t_s"].to_numpy(), one[label].to_numpy())
        t_ns = one["t_ns"].to_numpy()
        images = {}
        for finger, frames_ in raw.frames.items():
            picks = [int(np.argmin(np.abs(frames_.host_ns - t_ns[phases[p]]))) for p in figures.PHASES]
            images[finger] = [frames_.load(i) for i in picks]
        figures.pressing_strip(images, one["t_s"].to_numpy(), one[label].to_numpy(), label,
                               f"{name} ({one['pose'].iloc[0]}): one pressing cycle", figs / "pressing_strip.png")
