"""Finding DIGITs from sysfs, and the recorder's refusals before it touches a device."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from tactilepipe.core.errors import ArgumentError, InputError
from tactilepipe.rig.cameras import from_layout, list_digits, open_capture, resolve_source, to_layout
from tactilepipe.rig.record import install_calibration, next_trial_name
from tactilepipe.tool.formats.native_layout import write_calibration


def _usb_camera(root: Path, bus: str, product: str, serial: str, nodes: dict[str, int]) -> None:
    """A USB camera in a sysfs-like tree: the device with its attributes, an interface below it,
    and a video4linux entry per node whose `device` link points at the interface."""
    usb = root / "devices" / "usb1" / bus
    interface = usb / f"{bus}:1.0"
    interface.mkdir(parents=True)
    for name, value in {"idVendor": "2833", "product": product, "serial": serial, "manufacturer": "Facebook",
                        "bcdDevice": "0200"}.items():
        (usb / name).write_text(value + "\n")
    for node, index in nodes.items():
        entry = root / "class" / "video4linux" / node
        entry.mkdir(parents=True)
        (entry / "index").write_text(f"{index}\n")
        os.symlink(interface, entry / "device")


@pytest.fixture
def sysfs(tmp_path):
    _usb_camera(tmp_path, "1-1", "DIGIT", "D20262", {"video2": 0, "video3": 1})
    _usb_camera(tmp_path, "1-2", "Integrated Camera", "0001", {"video0": 0, "video1": 1})
    _usb_camera(tmp_path, "1-3", "DIGIT", "D20263", {"video4": 0, "video5": 1})
    return tmp_path / "class" / "video4linux"


def test_digits_are_found_by_their_capture_node_and_serial(sysfs):
    digits = list_digits(sysfs)
    assert [(d.node, d.serial, d.manufacturer, d.revision) for d in digits] == [
        ("/dev/video2", "D20262", "Facebook", "0200"), ("/dev/video4", "D20263", "Facebook", "0200")]
    assert resolve_source("D20263", sysfs) == "/dev/video4"
    assert resolve_source("/dev/video7", sysfs) == "/dev/video7"          # a node or a file is kept
    with pytest.raises(ArgumentError, match=r"no DIGIT with serial number D99999 .*D20262 at /dev/video2"):
        resolve_source("D99999", sysfs)
    assert list_digits(sysfs.parent / "nothing") == []


def test_frames_are_stored_as_digit_interface_turns_them():
    landscape = np.arange(240 * 320 * 3, dtype=np.uint32).reshape(240, 320, 3).astype(np.uint8)
    portrait = to_layout(landscape)
    assert portrait.shape == (320, 240, 3)
    # transpose, then flip upside down: the sensor's top-right corner lands at the top-left
    assert (portrait[0, 0] == landscape[0, -1]).all() and (portrait[-1, 0] == landscape[0, 0]).all()
    assert (from_layout(portrait) == landscape).all()


def test_bad_sources_and_modes_are_refused_by_name(tmp_path):
    with pytest.raises(InputError, match="no such camera source"):
        open_capture(str(tmp_path / "missing.mp4"), "qvga60")
    with pytest.raises(ArgumentError, match="camera mode 'vga60': choose one of qvga60"):
        open_capture(str(tmp_path / "f_%06d.png"), "vga60")


def test_a_session_keeps_one_calibration(tmp_path):
    from tactilepipe.tool.sim.plan import calibration_matrix
    from tactilepipe.core.config import load_params
    matrix = calibration_matrix(load_params())
    cal, other = tmp_path / "a.cal", tmp_path / "b.cal"
    write_calibration(cal, matrix)
    write_calibration(other, matrix * 1.1)
    session = tmp_path / "s"
    session.mkdir()
    with pytest.raises(ArgumentError, match="has no nano17.cal"):
        install_calibration(session, None)
    install_calibration(session, cal)
    assert (session / "nano17.cal").read_bytes() == cal.read_bytes()
    install_calibration(session, cal)                            # the same file again: fine
    with pytest.raises(ArgumentError, match="differs from"):
        install_calibration(session, other)
    write_calibration(other, matrix * 1e4)                      # no Nano17 maps 5 V to kN
    with pytest.raises(InputError, match="rated"):
        install_calibration(tmp_path / "s2", other)


def test_trials_are_numbered_after_the_last_one_taken(tmp_path):
    assert next_trial_name(tmp_path / "new", "knife_normal") == "knife_normal_000"
    (tmp_path / "knife_normal_000").mkdir()
    (tmp_path / "knife_normal_001").mkdir()
    assert next_trial_name(tmp_path, "knife_normal") == "knife_normal_002"


def test_a_device_thread_that_does_not_stop_is_reported_and_left_behind_in_bounded_time():
    import threading
    import time
    from tactilepipe.rig.reader import DeviceReader

    class Stuck(DeviceReader):            # a driver call that never returns (until the test ends)
        stats = {}
        closed = False

        def __init__(self):
            self.release = threading.Event()
            self._init_thread("stuck")

        def _run(self):
            self.release.wait(30)

        def _close(self):
            self.closed = True

    device = Stuck().start()
    t0 = time.monotonic()
    device.stop(timeout_s=0.3)
    assert time.monotonic() - t0 < 1.0
    assert device.stuck and device.running and not device.closed      # not released under the running call
    device.release.set()
    assert device._thread.join(5) is None and not device.running
