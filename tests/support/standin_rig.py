"""A stand-in for the study-000 rig, built from a simulated trial: the two DIGITs as image sequences
(in the orientation the sensor streams), and the Arduino as a separate process behind a real
pseudo-terminal, which `tactilepipe record` opens with pyserial like a USB serial port.

The stand-in Arduino behaves like the firmware docs/rig.md describes: it is reset when the port
opens, boots for ``boot_s``, then prints one line per sample at the simulated trial's rate on its
own millisecond clock, each line delayed by a random jitter; a few garbage lines are mixed in.
When the port closes it waits for the next open (the next trial). ``unplug_after_s`` makes it
vanish mid-trial (the pty closes); ``line_end`` is what ends each line (the firmware's ``\\n``,
or a board that ends them otherwise); ``reset_after_s`` reboots it once mid-trial (its clock
restarts from 0). It writes, for the test, one JSON line per open: when the port
opened and when the clock started (host ns), the simulated time of millis 0, and the garbage sent.
"""

from __future__ import annotations

import json
import os
import select
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np

from tactilepipe.rig.cameras import from_layout
from tactilepipe.tool.formats.native_layout import SENSORS

GARBAGE = [b"\x00\xff\xfe7,12\n", b"1234,512,512\n"]     # a corrupted line and a short one


def camera_sequences(sim: dict, folder: Path) -> dict[str, str]:
    """Each finger's simulated frames as an image sequence in the sensor's own (landscape)
    orientation; returns the OpenCV source string per sensor."""
    sources = {}
    for sensor in SENSORS:
        d = folder / sensor
        d.mkdir(parents=True, exist_ok=True)
        for k, frame in enumerate(sim["frames"][sensor]):
            cv2.imwrite(str(d / f"frame_{k:06d}.png"), from_layout(frame))
        sources[sensor] = str(d / "frame_%06d.png")
    return sources


def write_plan(sim: dict, path: Path, start_s: float = -0.3) -> None:
    """The samples the stand-in plays: simulated time (s from the first frame) and gauge counts,
    from ``start_s`` on."""
    tau = (sim["serial"]["sample_host_ns"] - sim["t0_ns"]) / 1e9
    keep = tau >= start_s
    np.savez(path, tau=tau[keep], counts=sim["serial"]["counts"][keep])


class StandInArduino:
    """The stand-in Arduino process; ``port`` is the pty's slave path to record from."""

    def __init__(self, plan: Path, truth: Path, boot_s: float = 0.25, jitter_ms: float = 4.0,
                 garbage_every: int = 17, unplug_after_s: float | None = None, seed: int = 0,
                 line_end: bytes = b"\n", reset_after_s: float | None = None):
        cmd = [sys.executable, __file__, str(plan), str(truth), str(boot_s), str(jitter_ms), str(garbage_every),
               str(unplug_after_s or 0), str(seed), line_end.hex(), str(reset_after_s or 0)]
        self.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True,
                                     env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})
        self.port = self.proc.stdout.readline().strip()
        self.truth = truth

    def records(self) -> list[dict]:
        return [json.loads(line) for line in self.truth.read_text().splitlines()] if self.truth.exists() else []

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
        self.proc.wait(10)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def _serve(plan: Path, truth: Path, boot_s: float, jitter_ms: float, garbage_every: int, unplug_after_s: float,
           seed: int, line_end: bytes = b"\n", reset_after_s: float = 0.0) -> None:
    master, slave = os.openpty()
    print(os.ttyname(slave), flush=True)
    os.close(slave)                       # from now on POLLHUP on the master means "port closed"
    poll = select.poll()
    poll.register(master, select.POLLHUP)
    rng = np.random.default_rng(seed)
    with np.load(plan) as z:
        tau, counts = z["tau"], z["counts"]
    while True:
        while (events := poll.poll(0)) and events[0][1] & select.POLLHUP:
            time.sleep(0.001)             # wait for the recorder to open the port
        opened_ns = time.time_ns()
        clock_ns = opened_ns + int(boot_s * 1e9)          # millis() starts after the reset's boot
        record = {"opened_ns": opened_ns, "clock_start_ns": clock_ns, "tau_at_millis0": float(tau[0]),
                  "garbage_lines": 0, "samples": 0}
        reset_ms = 0.0                                    # millis() at a reset mid-trial: it restarts from 0
        for i in range(len(tau) * 10):
            k = min(i, len(tau) - 1)                      # after the trial's end: the last sample again
            t_ms = (tau[k] - tau[0]) * 1000.0 if i < len(tau) else (tau[-1] - tau[0]) * 1000.0 + (i - k) * 66.7
            due_ns = clock_ns + int(t_ms * 1e6 + abs(rng.normal(0, jitter_ms)) * 1e6)
            while time.time_ns() < due_ns:
                if poll.poll(0):
                    break
                time.sleep(0.0005)
            if poll.poll(0):                              # the port closed: the trial is over
                break
            if unplug_after_s and time.time_ns() - opened_ns > unplug_after_s * 1e9:
                _write_truth(truth, record)
                os.close(master)                          # unplugged
                return
            if reset_after_s and not reset_ms and t_ms > reset_after_s * 1000:
                reset_ms = t_ms                           # a brown-out: the board reboots, its clock restarts
            lines = [f"{int(t_ms - reset_ms)},{','.join(str(int(c)) for c in counts[k])}".encode() + line_end]
            if garbage_every and i % garbage_every == garbage_every - 1:
                lines.insert(0, GARBAGE[(i // garbage_every) % len(GARBAGE)])
                record["garbage_lines"] += 1
            os.write(master, b"".join(lines))
            record["samples"] += 1
        _write_truth(truth, record)


def _write_truth(truth: Path, record: dict) -> None:
    with open(truth, "a") as f:
        f.write(json.dumps(record) + "\n")


if __name__ == "__main__":
    a = sys.argv[1:]
    _serve(Path(a[0]), Path(a[1]), float(a[2]), float(a[3]), int(a[4]), float(a[5]), int(a[6]), bytes.fromhex(a[7]),
           float(a[8]))
