"""A device read on its own thread: the lifecycle the rig's cameras and Arduino share."""

from __future__ import annotations

import threading


class DeviceReader:
    """Subclasses call ``_init_thread`` once the device is open, read in ``_run`` until
    ``_stop`` is set, release the device in ``_close`` and keep their counts in ``stats``."""

    stats: object

    def _init_thread(self, name: str) -> None:
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)

    def start(self):
        self._thread.start()
        return self

    def stop(self):
        """Stop reading (also before a start), release the device, and return the counts."""
        self._stop.set()
        if self._thread.ident is not None:         # started
            self._thread.join()
        self._close()
        return self.stats

    @property
    def running(self) -> bool:
        return self._thread.is_alive()

    def _run(self) -> None:
        raise NotImplementedError

    def _close(self) -> None:
        raise NotImplementedError
