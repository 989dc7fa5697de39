"""Which library files a pipeline stage runs, found from its imports (never listed by hand).

A stage is one function of the command line (`tactilepipe.cli.cmd_*`). Its code is:
- the CLI module itself and everything its module level imports;
- every module the stage function imports (the CLI imports lazily, inside each stage), and
  those imported by the module-level helpers of the CLI that the function calls;
- the transitive closure of those modules within `tactilepipe`, counting every import in a
  module, at module level or inside a function (conservative: an import that only one branch
  executes still counts), plus the `__init__.py` of each package on the way.

Snakemake rules list these files as inputs, so editing one re-runs exactly the rules whose stage
imports it; the dvc.yaml generator lists them as stage deps. The parameter keys a stage reads are
found the same way, from the keys it hands to `cli._params`, so both come from one place.
"""

from __future__ import annotations

import ast
import hashlib
from functools import lru_cache
from pathlib import Path

from tactilepipe.errors import TactilepipeError

PACKAGE = "tactilepipe"
PACKAGE_DIR = Path(__file__).resolve().parent
CLI_MODULE = f"{PACKAGE}.cli"


def module_path(module: str) -> Path | None:
    """File of a `tactilepipe...` module or package, or None if there is none."""
    parts = module.split(".")
    if parts[0] != PACKAGE:
        return None
    base = PACKAGE_DIR.joinpath(*parts[1:])
    for candidate in (base.with_suffix(".py"), base / "__init__.py"):
        if candidate.is_file():
            return candidate
    return None


@lru_cache(maxsize=None)
def _tree(path: Path) -> ast.Module:
    return ast.parse(path.read_text(), filename=str(path))


def _imports_in(node: ast.AST, module: str, is_package: bool) -> set[str]:
    """Modules of `tactilepipe` imported anywhere under ``node`` (``from a import b`` counts both
    a and a.b, since b may be a submodule)."""
    found = set()
    for n in ast.walk(node):
        if isinstance(n, ast.Import):
            found.update(a.name for a in n.names)
        elif isinstance(n, ast.ImportFrom):
            if n.level:
                anchor = module.split(".")
                anchor = anchor[:len(anchor) - n.level + (1 if is_package else 0)]
                base = ".".join(anchor + ([n.module] if n.module else []))
            else:
                base = n.module or ""
            found.add(base)
            found.update(f"{base}.{a.name}" for a in n.names)
    return {m for m in found if m.split(".")[0] == PACKAGE and module_path(m) is not None}


def _with_parents(module: str) -> set[str]:
    parts = module.split(".")
    return {".".join(parts[:i]) for i in range(1, len(parts) + 1)}


@lru_cache(maxsize=None)
def module_closure(module: str) -> frozenset[str]:
    """Every `tactilepipe` module that importing ``module`` can execute (itself included)."""
    seen: set[str] = set()
    todo = [module]
    while todo:
        m = todo.pop()
        for name in _with_parents(m):
            if name in seen or module_path(name) is None:
                continue
            seen.add(name)
            path = module_path(name)
            todo.extend(_imports_in(_tree(path), name, path.name == "__init__.py"))
    return frozenset(seen)


def _cli_functions() -> dict[str, ast.FunctionDef]:
    tree = _tree(module_path(CLI_MODULE))
    return {n.name: n for n in tree.body if isinstance(n, ast.FunctionDef)}


def _called_helpers(func: ast.FunctionDef, functions: dict[str, ast.FunctionDef]) -> list[ast.FunctionDef]:
    """``func`` and the module-level CLI functions it calls, directly or through each other."""
    out, todo, seen = [], [func], set()
    while todo:
        f = todo.pop()
        if f.name in seen:
            continue
        seen.add(f.name)
        out.append(f)
        todo.extend(functions[n.id] for n in ast.walk(f)
                    if isinstance(n, ast.Name) and n.id in functions and n.id != f.name)
    return out


def _stage_function(stage: str) -> ast.FunctionDef:
    functions = _cli_functions()
    if stage not in functions or not stage.startswith("cmd_"):
        raise TactilepipeError(f"no pipeline stage '{stage}' in {CLI_MODULE} "
                               f"(stages: {sorted(f for f in functions if f.startswith('cmd_'))})")
    return functions[stage]


@lru_cache(maxsize=None)
def stage_modules(stage: str) -> frozenset[str]:
    """Modules the CLI stage function ``stage`` (e.g. "cmd_report_volume") runs."""
    func = _stage_function(stage)
    tree = _tree(module_path(CLI_MODULE))
    top = ast.Module(body=[n for n in tree.body if isinstance(n, (ast.Import, ast.ImportFrom))], type_ignores=[])
    # the CLI module itself runs only its module level and the stage's functions, not every stage
    roots = _imports_in(top, CLI_MODULE, False)
    for f in _called_helpers(func, _cli_functions()):
        roots |= _imports_in(f, CLI_MODULE, False)
    # rules run `python -m tactilepipe`, which enters through the package's __main__
    closure: set[str] = _with_parents(CLI_MODULE) | {f"{CLI_MODULE.split('.')[0]}.__main__"}
    for m in roots:
        closure |= module_closure(m)
    return frozenset(closure)


def stage_files(stage: str, root: Path | None = None) -> list[str]:
    """Source files of ``stage``, sorted, as paths relative to ``root`` (default: the repository)."""
    root = root or PACKAGE_DIR.parents[1]
    return sorted(str(module_path(m).relative_to(root)) for m in stage_modules(stage))


def stage_param_keys(stage: str) -> tuple[str, ...]:
    """The dotted parameter keys the stage hands to `cli._params` (the only ones it can read)."""
    keys: list[str] = []
    for f in _called_helpers(_stage_function(stage), _cli_functions()):
        for n in ast.walk(f):
            if isinstance(n, ast.Call) and isinstance(n.func, ast.Name) and n.func.id == "_params":
                for arg in n.args[1:]:
                    if not (isinstance(arg, ast.Constant) and isinstance(arg.value, str)):
                        raise TactilepipeError(f"{CLI_MODULE}.{f.name}: _params keys must be string literals")
                    keys.append(arg.value)
    return tuple(dict.fromkeys(keys))


def stage_fingerprint(stage: str) -> str:
    """sha256 over the module names and file contents of the stage's code (one value per stage,
    the same wherever the package is installed)."""
    h = hashlib.sha256()
    for m in sorted(stage_modules(stage)):
        h.update(m.encode() + b"\0" + module_path(m).read_bytes() + b"\0")
    return h.hexdigest()
