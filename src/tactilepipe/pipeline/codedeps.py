"""Which library files a pipeline stage runs, found from its imports (never listed by hand).

A stage is a command of the command line, declared once with `@command("name", ...)` on its function
in its own module `tactilepipe.cli.<stage>` (cli/registry.py; a few commands that are no pipeline
stage share one: cli/rig.py), so that editing one stage re-runs that stage only.
Its code is:
- the entry files (`__main__`, `cli/main.py`) and what cli/main.py imports for every stage (the
  registry, `stage_params`), without the other stages' modules it imports;
- the stage's module, and of what its module level imports, what the stage uses: a ``from m
  import x`` counts when the stage function, the module-level helpers it calls, the constants
  they name or its own ``@command(...)`` declaration (argument choices, ``checks=``) read x
  (an import that names nothing to attribute, ``import m``, counts always);
- every module the stage function imports (stages import lazily, inside the function), and
  those imported by the module-level helpers of its module that the function calls;
- the transitive closure of those modules within `tactilepipe`, counting every import in a
  module, at module level or inside a function (conservative: an import that only one branch
  executes still counts), plus the `__init__.py` of each package on the way.

Snakemake rules list these files as inputs, so editing one re-runs exactly the rules whose stage
imports it; the dvc.yaml generator lists them as stage deps. The parameter keys a stage reads, and
those the rules read to shape its jobs, are read from the same declaration (its ``params=`` and
``graph=``), from the source, so that Snakemake's start imports no stage module.
"""

from __future__ import annotations

import ast
import hashlib
from functools import lru_cache
from pathlib import Path

from tactilepipe.core.errors import TactilepipeError
from tactilepipe.core import sourcecache
from tactilepipe.core.sourcecache import PACKAGE_DIR

PACKAGE = PACKAGE_DIR.name
CLI_PACKAGE = f"{PACKAGE}.cli"
ENTRY = f"{CLI_PACKAGE}.main"
CLOSURE_CACHE = "stage-modules"


@lru_cache(maxsize=None)
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
    for n in _import_statements(node):
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


_BLOCKS = ("body", "orelse", "finalbody", "handlers", "cases")


def _import_statements(node: ast.AST):
    """The import statements under ``node``, at any depth of nested blocks (functions, classes,
    if/try/with/for/match). An import is a statement, so expressions are not walked: that makes
    this several times faster than ``ast.walk``, which every Snakemake start pays per module."""
    todo = [node]
    while todo:
        n = todo.pop()
        if isinstance(n, (ast.Import, ast.ImportFrom)):
            yield n
            continue
        for field in _BLOCKS:
            todo.extend(getattr(n, field, ()))


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
            todo.extend(module_imports(name))
    return frozenset(seen)


@lru_cache(maxsize=None)
def module_imports(module: str) -> frozenset[str]:
    """The `tactilepipe` modules ``module`` imports anywhere in its file, at module level or inside a
    function (walked once per module: every Snakemake start computes the closures of all stages)."""
    path = module_path(module)
    return frozenset(_imports_in(_tree(path), module, path.name == "__init__.py"))


def _study_modules() -> list[str]:
    """The CLI's per-study modules (every ``cli/*.py`` but the entry point and the shared helpers)."""
    return sorted(f"{CLI_PACKAGE}.{f.stem}" for f in module_path(CLI_PACKAGE).parent.glob("*.py")
                  if f.stem not in {"__init__", ENTRY.rsplit(".", 1)[1]})


def _functions(module: str) -> dict[str, ast.FunctionDef]:
    return {n.name: n for n in _tree(module_path(module)).body if isinstance(n, ast.FunctionDef)}


def _declaration(func: ast.FunctionDef) -> ast.Call | None:
    """The ``@command("name", ...)`` call decorating ``func`` (cli/registry.py), if any."""
    for d in func.decorator_list:
        if isinstance(d, ast.Call) and isinstance(d.func, ast.Name) and d.func.id == "command" and d.args \
                and isinstance(d.args[0], ast.Constant) and isinstance(d.args[0].value, str):
            return d
    return None


@lru_cache(maxsize=None)
def _declared_stages() -> dict[str, tuple[str, str]]:
    """{command name: (module, function)} of every command the CLI modules declare."""
    out = {}
    for m in _study_modules():
        for name, f in _functions(m).items():
            call = _declaration(f)
            if call is not None:
                out[call.args[0].value] = (m, name)
    return out


def _declared_keys(stage: str, keyword: str) -> tuple[str, ...]:
    module, name = _home(stage)
    call = _declaration(_functions(module)[name])
    for kw in call.keywords:
        if kw.arg == keyword:
            values = kw.value.elts if isinstance(kw.value, (ast.Tuple, ast.List)) else None
            if values is None or not all(isinstance(v, ast.Constant) and isinstance(v.value, str) for v in values):
                raise TactilepipeError(f"{module}.{name}: the {keyword}= of its declaration must be a tuple of "
                                       f"string literals")
            return tuple(v.value for v in values)
    return ()


def _home(stage: str) -> tuple[str, str]:
    """(module, function) of the declared stage ``stage``."""
    homes = _declared_stages()
    if stage not in homes:
        raise TactilepipeError(f"no pipeline stage '{stage}' declared in {CLI_PACKAGE} (stages: {sorted(homes)})")
    return homes[stage]


def stage_modules(stage: str) -> frozenset[str]:
    """Modules the declared stage ``stage`` (a command name, e.g. "volume-report") runs.

    Every Snakemake start asks this for every stage, and every SLURM job starts Snakemake twice,
    so the answers are kept for the exact source they came from (sourcecache)."""
    _home(stage)                              # an unknown stage is an error, cached or not
    return frozenset(_stored_closures()[stage])


@lru_cache(maxsize=None)
def _stored_closures() -> dict[str, list[str]]:
    """Every stage's closure: read back for this exact source, else computed all at once and stored."""
    stored = sourcecache.read(CLOSURE_CACHE)
    if stored:
        return stored
    stages = sorted(_declared_stages())
    closures = {s: sorted(_stage_closure(s)) for s in stages}
    sourcecache.write(CLOSURE_CACHE, closures)
    return closures


def _stage_closure(stage: str) -> frozenset[str]:
    home, func = _home(stage)
    tree = _tree(module_path(home))
    # the stage's module runs its module level and the stage's functions, not its other stages
    used, names = _used_definitions(tree, _functions(home)[func])
    roots = _module_level_imports(tree, home, names)
    for node in used:
        roots |= _imports_in(node, home, False)
    # rules run `python -m tactilepipe`, which enters through __main__ and the parser of every
    # study (cli.main): those files count, and what cli.main imports for every stage (the shared
    # helpers: stage_params, the registry), but not the other studies' modules it imports
    closure: set[str] = _with_parents(home) | {f"{PACKAGE}.__main__", ENTRY}
    studies = {m for m, _ in _declared_stages().values()}
    for m in roots | (module_imports(ENTRY) - studies):
        closure |= module_closure(m)
    return frozenset(closure)


_DEFINITIONS = (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)


def _used_definitions(tree: ast.Module, func: ast.FunctionDef) -> tuple[list[ast.AST], set[str]]:
    """The module-level definitions the stage function ``func`` uses (itself with its ``@command``
    declaration, the helpers it calls, the constants it or its declaration names, e.g. an argument
    with ``choices``, its ``checks``), transitively; and every name they read."""
    defined: dict[str, list[ast.AST]] = {}
    for node in tree.body:
        if isinstance(node, _DEFINITIONS):
            defined.setdefault(node.name, []).append(node)
        elif isinstance(node, (ast.Assign, ast.AnnAssign, ast.AugAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            for target in targets:
                for n in ast.walk(target):
                    if isinstance(n, ast.Name):
                        defined.setdefault(n.id, []).append(node)
    used, names, seen, todo = [], set(), set(), [func]
    while todo:
        node = todo.pop()
        if id(node) in seen:
            continue
        seen.add(id(node))
        used.append(node)
        for n in ast.walk(node):
            if isinstance(n, ast.Name) and n.id not in names:
                names.add(n.id)
                todo.extend(defined.get(n.id, ()))
    return used, names


def _module_level_imports(tree: ast.Module, module: str, names: set[str]) -> set[str]:
    """The modules imported at the top of the stage's module that the stage uses: a ``from m
    import x`` counts if the stage reads the name x (or its alias), an ``import m as y`` if it
    reads y. What cannot be attributed by name counts always (``import m``, ``from m import *``,
    an import inside a module-level if or try)."""
    found: set[str] = set()
    for node in tree.body:
        if isinstance(node, _DEFINITIONS) or isinstance(node, (ast.Assign, ast.AnnAssign, ast.AugAssign)):
            continue
        if isinstance(node, ast.ImportFrom) and all(a.name != "*" for a in node.names):
            kept = [a for a in node.names if (a.asname or a.name) in names]
            if kept:
                found |= _imports_in(ast.ImportFrom(module=node.module, names=kept, level=node.level), module, False)
        elif isinstance(node, ast.Import):
            kept = [a for a in node.names if a.asname is None or a.asname in names]
            if kept:
                found |= _imports_in(ast.Import(names=kept), module, False)
        else:
            found |= _imports_in(node, module, False)
    return found


def stage_files(stage: str, root: Path | None = None) -> list[str]:
    """Source files of ``stage``, sorted, as paths relative to ``root`` (default: the repository)."""
    root = root or PACKAGE_DIR.parents[1]
    return sorted(str(module_path(m).relative_to(root)) for m in stage_modules(stage))


def stage_param_keys(stage: str) -> tuple[str, ...]:
    """The dotted parameter keys the stage declares (``params=``: the only ones it can read)."""
    return _declared_keys(stage, "params")


def stage_graph_keys(stage: str) -> tuple[str, ...]:
    """The keys its declaration says the rules read to shape the stage's jobs (``graph=``)."""
    return _declared_keys(stage, "graph")


def stage_fingerprint(stage: str) -> str:
    """sha256 over the module names and file contents of the stage's code (one value per stage,
    the same wherever the package is installed)."""
    h = hashlib.sha256()
    for m in sorted(stage_modules(stage)):
        h.update(m.encode() + b"\0" + module_path(m).read_bytes() + b"\0")
    return h.hexdigest()


def declared_stage_names() -> list[str]:
    """Every stage the CLI modules declare."""
    return sorted(_declared_stages())


def _declared_literal(stage: str, keyword: str):
    """The literal value of ``keyword=`` in the stage's declaration, or None when it has none."""
    module, name = _home(stage)
    for kw in _declaration(_functions(module)[name]).keywords:
        if kw.arg == keyword:
            try:
                return ast.literal_eval(kw.value)
            except ValueError:
                raise TactilepipeError(f"{module}.{name}: the {keyword}= of its declaration must be a literal "
                                       f"(strings, dicts, booleans), so the workflow can read it unimported") from None
    return None


def stage_rule(stage: str) -> dict | None:
    """The workflow rule the stage declares (``rule=``), or None: its rule is written by hand."""
    return _declared_literal(stage, "rule")


def stage_flags(stage: str) -> set[str]:
    """The option flags (``--name``) of the stage's declared arguments that are written literally."""
    module, name = _home(stage)
    call = _declaration(_functions(module)[name])
    found = set()
    for node in ast.walk(call):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "arg":
            found.update(a.value for a in node.args if isinstance(a, ast.Constant) and isinstance(a.value, str)
                         and a.value.startswith("--"))
    # arguments shared through a tuple (e.g. FOLDED) are found where that tuple is made: in the
    # stage's module, or in the module it imports the name from (cli/volume_args.py)
    names = {n.id for n in ast.walk(call) if isinstance(n, ast.Name)}
    for value in _assigned(module, names) + [v for source, imported in _imported_names(module, names).items()
                                             for v in _assigned(source, imported)]:
        for sub in ast.walk(value):
            if isinstance(sub, ast.Call) and isinstance(sub.func, ast.Name) and sub.func.id == "arg":
                found.update(a.value for a in sub.args if isinstance(a, ast.Constant)
                             and isinstance(a.value, str) and a.value.startswith("--"))
    return found


def _assigned(module: str, names: set[str]) -> list[ast.AST]:
    """The values the module level of ``module`` assigns to any of ``names``."""
    return [node.value for node in _tree(module_path(module)).body if isinstance(node, ast.Assign)
            and any(isinstance(t, ast.Name) and t.id in names for t in node.targets)]


def _imported_names(module: str, names: set[str]) -> dict[str, set[str]]:
    """{tactilepipe module: the names of ``names`` the module level of ``module`` imports from it}."""
    out: dict[str, set[str]] = {}
    for node in _tree(module_path(module)).body:
        if isinstance(node, ast.ImportFrom) and node.module and module_path(node.module) is not None:
            hit = {a.name for a in node.names if (a.asname or a.name) in names}
            if hit:
                out.setdefault(node.module, set()).update(hit)
    return out
