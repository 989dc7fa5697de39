"""A device read on its own thread: the lifecycle the rig's cameras and Arduino share.

Every read a device makes has a deadline (a serial port's timeout, a camera's frame timeout), so
a thread sees ``stop`` within one deadline; and ``stop`` itself waits for the thread at most
``STOP_TIMEOUT_S``. A thread still running then (a driver call that never returns) is reported
(``stuck``) and left behind with its device: it is a daemon, so the command still exits."""

from __future__ import annotations

import threading

STOP_TIMEOUT_S = 2.0                 # ten read deadlines of the Arduino's port, two camera timeouts


class DeviceReader:
    """Subclasses call ``_init_thread`` once the device is open, read in ``_run`` until
    ``_stop`` is set, release the device in ``_close`` and keep their counts in ``stats``."""

    stats: object
    stuck: bool = False               # its thread did not stop within STOP_TIMEOUT_S

    def _init_thread(self, name: str) -> None:
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)

    def start(self):
        self._thread.start()
        return self

    def stop(self, timeout_s: float = STOP_TIMEOUT_S):
        """Stop reading (also before a start), release the device, and return the counts; within
        ``timeout_s`` whatever the thread does (``stuck`` says it did not stop)."""
        self._stop.set()
        if self._thread.ident is not None:         # started
            self._thread.join(timeout_s)
            self.stuck = self._thread.is_alive()
        if not self.stuck:                         # a device released under a running read can crash
            self._close()                          # its driver: a stuck one is left to the process exit
        return self.stats

    @property
    def running(self) -> bool:
        return self._thread.is_alive()

    def _run(self) -> None:
        raise NotImplementedError

    def _close(self) -> None:
        raise NotImplementedError
