"""Errors a user can act on: each names the file (and record) and what is wrong."""

from __future__ import annotations

from pathlib import Path


class TactilepipeError(Exception):
    """Base class; the CLI prints these as one clear line instead of a traceback."""


class InputError(TactilepipeError):
    """Bad input data: names the file, optionally the record, and the problem."""

    def __init__(self, path: str | Path, problem: str, record: str | int | None = None):
        self.path = str(path)
        # one line, whatever a library put in its message (YAML and Arrow errors span several)
        problem = " / ".join(line.strip() for line in str(problem).splitlines() if line.strip())
        self.problem = problem
        self.record = record
        where = self.path if record is None else f"{self.path} [{record}]"
        super().__init__(f"{where}: {problem}")

    def __reduce__(self):
        # rebuilt from its own arguments, so it survives the trip back from a worker process
        return type(self), (self.path, self.problem, self.record)


class ConfigError(TactilepipeError):
    """params.yaml (or an override) is invalid."""


class ArgumentError(TactilepipeError, ValueError):
    """A bad argument: names it and the values it may take (or what is wrong with it).

    Also raised for malformed data handed to a function that does not know where it came from
    (e.g. message bytes: "record 3: ..."); the caller that read the file re-raises it as an
    InputError naming the file and the record. A ValueError as well, so ``except ValueError``
    (argparse type functions, callers that wrap decoding errors) keeps working."""
