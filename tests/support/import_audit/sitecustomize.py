"""Loaded by every Python process of an audited build (this folder is put first on PYTHONPATH):
at exit, the process writes its command line and the tactilepipe modules it imported into the
folder $TACTILEPIPE_IMPORT_AUDIT (tests/support/read_audit.py compares them with each rule's code)."""

import atexit
import json
import os
import sys
import time

_OUT = os.environ.get("TACTILEPIPE_IMPORT_AUDIT")

if _OUT:
    def _write() -> None:
        modules = sorted({getattr(m, "__file__", None) or "" for name, m in list(sys.modules.items())
                          if name == "tactilepipe" or name.startswith("tactilepipe.")} - {""})
        # process ids are reused within a build: the time keeps each process's record apart
        with open(os.path.join(_OUT, f"{os.getpid()}-{time.time_ns()}.json"), "w") as f:
            json.dump({"argv": sys.argv, "orig_argv": getattr(sys, "orig_argv", []), "modules": modules}, f)

    atexit.register(_write)
