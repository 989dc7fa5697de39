"""One declaration per command: its name, help, arguments, and for a pipeline stage the parameters
it reads and the ones the workflow reads to shape its jobs.

A stage's module (cli/<stage>.py) declares its command on its function::

    @command("volume-split", "seeded train/test lift draws stratified by volume",
           params=("seed", "folds"), checks=VOLUME_CHECKS,
           args=(arg("--dataset", required=True), arg("--out", required=True)))
    def cmd_volume_split(args, p): ...

From that one declaration:
- the command line builds the sub-command (``add_commands``) and hands the function its
  parameters, cut down to ``params`` (``p``; reading any other key is an error); run by hand, it
  first runs ``checks``, its study's cross-key checks (``check(p, source)`` of volume/checks.py,
  tool/checks.py, papillarray/checks.py) on the whole resolved params.yaml; under the workflow
  a stage reads its stamp, whose values the workflow checked with every study's checks;
- the workflow (``pipeline/codedeps.py``, which reads the declarations from the source without
  importing them) stamps the values of ``params`` and ``graph`` (results/<build>/params/<name>.json), lists
  them as the DVC stage's params, and takes the function's imports, and those of the names the
  function and its declaration use (``checks``, argument choices), as the stage's code.
``params`` and ``graph`` must be tuples of string literals, so that they can be read that way.

A stage with one fixed file per input and output declares its workflow rule too, as a literal::

    rule={"scene": "volume", "inputs": {"dataset": "volume/dataset.parquet"},
          "outputs": {"out": "volume/folds.json"}}

(paths under the build's folder, each key one of its ``--<key>`` arguments): the workflow then
generates its Snakemake rule, its outputs join the scene's targets and so its DVC stage.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

from tactilepipe.core.errors import TactilepipeError


@dataclass(frozen=True)
class Arg:
    flags: tuple[str, ...]
    options: dict = field(default_factory=dict)


def arg(*flags: str, **options) -> Arg:
    """An argument as ``argparse.ArgumentParser.add_argument`` takes it."""
    return Arg(flags, options)


@dataclass(frozen=True)
class Command:
    name: str
    func: Callable
    help: str
    params: tuple[str, ...]        # dotted keys of params.yaml the command reads (its only way in)
    graph: tuple[str, ...]         # keys the rules read to decide its jobs or their arguments
    checks: tuple[Callable, ...]   # its study's cross-key checks, run on params.yaml by hand
    args: tuple[Arg, ...]
    provenance: bool               # takes --provenance-stages / --sessions (a scene's report)
    parser_options: dict           # more of add_parser's keywords (description, formatter_class)
    rule: dict | None = None       # the workflow's rule, generated (pipeline/stage_rules.py)


COMMANDS: dict[str, Command] = {}


def command(name: str, help: str, *, params: tuple[str, ...] = (), graph: tuple[str, ...] = (),
            checks: tuple[Callable, ...] = (), args: tuple[Arg, ...] = (), provenance: bool = False,
            rule: dict | None = None, **parser_options):
    """Declare the decorated function ``f(args, p)`` as the command ``name``."""
    def register(func: Callable) -> Callable:
        if name in COMMANDS:
            raise TactilepipeError(f"command '{name}' is declared twice ({COMMANDS[name].func.__module__} and "
                                   f"{func.__module__})")
        if params and not checks:
            raise TactilepipeError(f"command '{name}' ({func.__module__}) reads parameters but declares no checks=: "
                                   f"name its study's (e.g. VOLUME_CHECKS), so that run by hand it refuses what the "
                                   f"workflow refuses")
        COMMANDS[name] = Command(name, func, help, tuple(params), tuple(graph), tuple(checks), tuple(args),
                                 provenance, parser_options, rule)
        return func
    return register


def add_commands(sub, settings, provenance) -> None:
    """A sub-parser per declared command: ``settings`` (--params, --scale, --override) for those
    that read parameters, ``provenance`` for the scene reports."""
    for c in COMMANDS.values():
        parents = ([settings] if c.params else []) + ([provenance] if c.provenance else [])
        s = sub.add_parser(c.name, parents=parents, help=c.help, **c.parser_options)
        for a in c.args:
            s.add_argument(*a.flags, **a.options)
        s.set_defaults(command_spec=c)
