"""The command line: one parser over every study's stages; errors print one line, no traceback."""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys

import tactilepipe.cli
from tactilepipe.cli.common import stage_params
from tactilepipe.cli.registry import add_commands
from tactilepipe.core import vector_dispatch
from tactilepipe.core.errors import TactilepipeError


# Importing a stage's module declares its command (a stage is one module, so that editing it
# re-runs that stage only). Every module of this package but the shared ones declares commands,
# found rather than listed, so that a new stage's module is the only file it adds
# (pipeline/codedeps.py finds them the same way); --help lists these first, in this order.
SHARED = {"main", "common", "registry", "provenance", "tool_args", "volume_args"}
FIRST = ("volume_simulate", "papillarray_ingest", "volume_dataset", "volume_split", "volume_train",
         "volume_gridsearch", "volume_baseline", "volume_report", "volume_regimes", "drift_simulate",
         "drift_report", "tool_simulate", "tool_ingest", "tool_clock_figure", "tool_dataset", "tool_split",
         "tool_train", "tool_model_report", "tool_data_report", "predict", "realism", "portability",
         "study000_unpack", "tool_evaluate", "study000_table", "rig", "compare", "sessions")


def declare_commands() -> None:
    """Import every command's module (once). A module that cannot be imported, or declares a
    command wrongly, is one error naming its file."""
    found = {m.name for m in pkgutil.iter_modules(tactilepipe.cli.__path__)} - SHARED
    for name in [m for m in FIRST if m in found] + sorted(found - set(FIRST)):
        module = f"tactilepipe.cli.{name}"
        try:
            importlib.import_module(module)
        except TactilepipeError:
            raise
        except Exception as exc:                  # a new stage's module with a mistake in it
            where = f"{tactilepipe.cli.__path__[0]}/{name}.py"
            raise TactilepipeError(f"{where}: cannot be imported ({type(exc).__name__}: {exc})") from None


def build_parser() -> argparse.ArgumentParser:
    declare_commands()
    parser = argparse.ArgumentParser(prog="tactilepipe", description="every pipeline stage of tactilepipe")
    parser.add_argument("--version", action=_PrintVersion)
    settings = argparse.ArgumentParser(add_help=False)
    settings.add_argument("--params", default="params.yaml", help="parameter file (default: params.yaml)")
    settings.add_argument("--scale", help="smoke | default | paper (overrides params.yaml)")
    settings.add_argument("--override", help="JSON object merged over params.yaml before validation")
    settings.add_argument("--stamp", help="the workflow's parameter stamp of this stage (results/<build>/params/<stage>.json): "
                                          "its values instead of params.yaml")
    provenance = argparse.ArgumentParser(add_help=False)
    provenance.add_argument("--provenance-stages", nargs="*", default=[], metavar="STAGE",
                            help="pipeline stages whose code and parameters made this scene")
    provenance.add_argument("--provenance-stamps", nargs="*", default=[], metavar="STAMP",
                            help="the parameter stamp of a stage of --provenance-stages kept elsewhere than beside "
                                 "--stamp (a simulator's, in its scale's folder: results/<scale>/params/)")
    provenance.add_argument("--sessions", nargs="*", default=[], help="the scene's input recording sessions")
    sub = parser.add_subparsers(dest="command", required=True, metavar="STAGE")
    add_commands(sub, settings, provenance)
    return parser


class _PrintVersion(argparse.Action):
    """--version: the version and the checkout's commit, asked of git only when the option is given."""

    def __init__(self, option_strings, dest, **kwargs):
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS,
                         help="print the version, the git commit of the checkout the code is imported from, and exit")

    def __call__(self, parser, namespace, values, option_string=None):
        print(version_line())
        parser.exit()


def version_line() -> str:
    """The version, the commit of the checkout the package is imported from ("modified" when its
    code or parameters have uncommitted changes) and that folder: two checkouts sharing a venv
    cannot be mistaken for each other."""
    from pathlib import Path
    from tactilepipe.core.environment import git_state
    package = Path(tactilepipe.__file__).resolve().parent
    state = git_state(package.parents[1])        # src/tactilepipe -> the checkout
    if state["commit"] is None:
        where = "not in a git checkout"
    else:
        where = f"commit {state['commit'][:12]}" + (", modified" if state["uncommitted_changes"] else "")
    return f"tactilepipe {tactilepipe.__version__} ({where}) from {package}"


def main(argv: list[str] | None = None) -> int:
    vector_dispatch.pin()                     # before any stage loads NumPy or OpenCV: they read it then
    try:
        parser = build_parser()               # declares every study's commands
    except TactilepipeError as exc:
        print(f"tactilepipe: error: {exc}", file=sys.stderr)
        return 2
    args = parser.parse_args(argv)
    spec = args.command_spec
    try:
        p = stage_params(args, *spec.params, checks=spec.checks) if spec.params else {}
        status = spec.func(args, p)       # a command may return an exit status (diff: 1 on a regression)
    except TactilepipeError as exc:
        print(f"tactilepipe {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        # the machine, not the data: a full disk, a read-only or forbidden folder, a size limit,
        # a file that vanished. One line naming the file, no traceback.
        print(f"tactilepipe {args.command}: error: {_os_error_line(exc)}", file=sys.stderr)
        return 1
    return status or 0


def _os_error_line(exc: OSError) -> str:
    """'<path>: <problem>' of an OSError (pyarrow and numpy often leave filename unset)."""
    import os
    problem = exc.strerror or (os.strerror(exc.errno) if exc.errno else str(exc) or type(exc).__name__)
    if exc.filename is None:
        return f"{problem} ({str(exc).strip() or type(exc).__name__})" if str(exc) != problem else problem
    where = f"{exc.filename} -> {exc.filename2}" if exc.filename2 else str(exc.filename)
    return f"{where}: {problem}"
