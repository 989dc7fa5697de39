"""The repository as a newcomer meets it: a short README whose links and promised places exist,
short library modules whose packages import each other one way only, no torch.load that could run
a pickle's code, and no pointer to material outside the repository."""

from __future__ import annotations

import ast
import fnmatch
import functools
import os
import re
import subprocess

import pytest

from tactilepipe.pipeline.codedeps import PACKAGE, module_imports

from support.project import REPO

LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")
# spelled in two parts so that this file does not match itself
OUTSIDE = [re.compile(p) for p in (r"\.\./" + "shared", "REFERENCE" + r"\.md", r"\b[Ii]ssue" + r" #?\d+")]


@functools.cache
def _git_files() -> tuple[str, ...] | None:
    try:
        return tuple(subprocess.run(["git", "ls-files"], cwd=REPO, capture_output=True, text=True,
                                    check=True).stdout.split())
    except (OSError, subprocess.CalledProcessError):
        return None


def tracked_names() -> tuple[str, ...]:
    if (names := _git_files()) is None:
        pytest.skip("not a git checkout")
    return names


def tracked_text_files():
    for name in tracked_names():
        path = REPO / name
        if path.suffix in {".png", ".pdf", ".npy", ".parquet", ".pt", ".bag", ".jpg"} or not path.is_file():
            continue
        try:
            yield name, path.read_text()
        except UnicodeDecodeError:
            continue


def test_readme_is_short():
    assert len((REPO / "README.md").read_bytes()) <= 7200


def test_the_docs_read_in_an_hour():
    # reference and how-to pages, not a notebook: dated measurements live in benchmarks/record.md
    sizes = {p.name: len(p.read_bytes()) for p in (REPO / "docs").glob("*.md")}
    assert not {n: s for n, s in sizes.items() if s > 20_000}, sizes
    assert sum(sizes.values()) < 120_000, sum(sizes.values())


def test_links_of_the_readme_and_docs_exist():
    for page in [REPO / "README.md", *(REPO / "docs").rglob("*.md")]:
        for target in LINK.findall(page.read_text()):
            if "://" not in target and not target.startswith("mailto:"):
                assert (page.parent / target).exists(), f"{page.relative_to(REPO)} links to missing {target}"


def newcomer_paths(readme: str) -> list[tuple[str, str]]:
    """(docs page, result) for each page of docs/ the README links and each committed file under
    results/ that page links or names in backticks."""
    files = set(tracked_names()) - {"results/README.md"}
    paths = []
    for page in {t for t in LINK.findall(readme) if re.fullmatch(r"docs/[\w-]+\.md", t)}:
        text = (REPO / page).read_text()
        named = [os.path.normpath(f"docs/{t}") for t in LINK.findall(text)] + CODE_SPAN.findall(text)
        paths += [(page, name) for name in named if name.startswith("results/") and name in files]
    return paths


def test_the_readme_leads_through_a_docs_page_to_a_committed_result():
    readme = (REPO / "README.md").read_text()
    assert newcomer_paths(readme), "no page of docs/ the README links names a committed file under results/"
    assert not newcomer_paths(re.sub(r"\]\(docs/[^)]*\)", "]()", readme)), "the path must go through the README's links"


def test_the_places_the_readme_promises_exist():
    src = REPO / "src" / "tactilepipe"
    assert "class ToolFrames" in (src / "tool" / "data" / "loader.py").read_text()
    assert re.search(r"^def defined_variants\b", (src / "tool" / "model" / "variants.py").read_text(), re.M)
    assert re.search(r"^tool_variants:", (REPO / "params.yaml").read_text(), re.M)
    figures = list((src / "tool" / "report").glob("figures_*.py"))
    assert figures and all("savefig" in f.read_text() or "save_figure" in f.read_text() for f in figures)


# What the pages may name: every backticked `tactilepipe X`, `make X` and `snakemake ... RULE`, and
# every backticked dotted key `group.key` of a params.yaml group. The decision records are left
# out: they record what was run then, under the names of the time.
DOC_PAGES = ["README.md", "tests/README.md", "results/README.md"]
CODE_SPAN = re.compile(r"`([^`\n]+)`")
COMMAND = re.compile(r"(?:^|[\s/])(tactilepipe|make|snakemake)((?:\s+[^\s;|&#]+)*)")
PARAM_KEY = re.compile(r"^[a-z][a-z0-9_]*(?:\.[a-z0-9_]+)+$")


def doc_pages():
    pages = [REPO / p for p in DOC_PAGES] + sorted((REPO / "docs").glob("*.md"))
    for page in pages:
        text = page.read_text()
        # code blocks are read as code spans line by line
        spans = CODE_SPAN.findall(re.sub(r"```.*?```", "", text, flags=re.S))
        for block in re.findall(r"```[a-z]*\n(.*?)```", text, flags=re.S):
            spans += [line.split("#")[0] for line in block.splitlines()]
        yield page.relative_to(REPO), spans


FILE_SUFFIXES = {"py", "md", "json", "yaml", "smk", "csv", "png", "parquet", "npy", "pt", "log", "txt", "rst", "html"}


def names_in_docs(pages=None):
    """(page, kind, name) of every command, rule and parameter key the pages name."""
    import yaml
    groups = set(yaml.safe_load((REPO / "params.yaml").read_text()))
    for page, spans in pages if pages is not None else doc_pages():
        for span in spans:
            for tool, rest in COMMAND.findall(span):
                words = rest.split()
                if tool == "tactilepipe" and words and re.fullmatch(r"[a-z][a-z0-9-]*:?", words[0]):
                    yield page, "command", words[0].rstrip(":")      # "tactilepipe X: error ..." is X's
                elif tool == "make" and words and re.fullmatch(r"[a-z][\w.-]*", words[0]):
                    yield page, "make target", words[0]
                elif tool == "snakemake":
                    for before, word in zip(["snakemake"] + words, words):
                        # a bare name that is not an option's value is a rule (a path or key=value is not)
                        if re.fullmatch(r"[a-z][a-z0-9_]*", word) and not before.startswith("-"):
                            yield page, "rule", word
            if PARAM_KEY.match(span.strip()) and span.split(".")[0] in groups and \
                    span.strip().rsplit(".", 1)[1] not in FILE_SUFFIXES:
                yield page, "key", span.strip()


def _known_names() -> dict[str, set[str]]:
    from tactilepipe.cli.main import declare_commands
    from tactilepipe.cli.registry import COMMANDS
    declare_commands()
    makefile = (REPO / "Makefile").read_text()
    from tactilepipe.pipeline.scenes import SCENES
    from tactilepipe.pipeline.stage_rules import stage_rules
    rules = {m for f in [REPO / "Snakefile", *(REPO / "workflow/rules").glob("*.smk")]
             for m in re.findall(r"^rule (\w+):", f.read_text(), re.M)}
    # and the rules workflow/rules/stages.smk makes: a target per scene, a rule per declaring stage
    rules |= set(SCENES) | {r.name for r in stage_rules()}
    return {"command": set(COMMANDS), "make target": set(re.findall(r"^([\w.-]+):", makefile, re.M)),
            "rule": rules}


def _has_key(tree, key: str) -> bool:
    node = tree
    for part in key.split("."):
        if not isinstance(node, dict) or part not in node:
            return False
        node = node[part]
    return True


def test_the_commands_rules_and_keys_the_docs_name_exist():
    import yaml
    known = _known_names()
    params = yaml.safe_load((REPO / "params.yaml").read_text())
    missing = sorted({f"{page}: {kind} `{name}`" for page, kind, name in names_in_docs()
                      if not (_has_key(params, name) if kind == "key" else name in known[kind])})
    assert not missing, "the docs name what does not exist:\n" + "\n".join(missing)


def test_the_docs_check_finds_a_missing_command_rule_and_key():
    text = ("Run `tactilepipe unpack-public`, `make cleanall`, `snakemake --cores 2 simulate_tool`, "
            "and set `tool_train.no_such_key`; `make smoke` and `tool_train.image_size` exist.")
    found = {(kind, name) for _, kind, name in names_in_docs([("page.md", CODE_SPAN.findall(text))])}
    assert found >= {("command", "unpack-public"), ("make target", "cleanall"), ("rule", "simulate_tool"),
                     ("key", "tool_train.no_such_key"), ("make target", "smoke"), ("key", "tool_train.image_size")}
    known = _known_names()
    assert "unpack-public" not in known["command"] and "cleanall" not in known["make target"]
    assert "simulate_tool" not in known["rule"] and "tool_simulate" in known["rule"] and "smoke" in known["make target"]


# What params.yaml's comments and the pages cite: a repository path (a glob names one file), a
# section as `docs/page.md, "Heading"` (a heading, or its part before a colon), a decision by its
# number, a decision record by its file name. A path holding <...> or {...} is a pattern, not a path;
# a module path outside those roots (`tool/data/witness.py`, `estimate.py`) is one of the library's.
ROOTS = r"(?:docs|studies|src|benchmarks|workflow|results|tests)/"
REPO_PATH = re.compile(rf"(?<![\w/.-]){ROOTS}[\w./*<>{{}}-]*")
MODULE = re.compile(rf"(?<![\w/.-])(?!{ROOTS})\w[\w/]*\.py\b")
SECTION = re.compile(r'(docs/[\w/-]+\.md),?\s*"([^"\n]+)"')
DECISION = re.compile(r"\b[Dd]ecisions?\s+(\d{4}(?:(?:,\s*|\s+and\s+|\s+or\s+)\d{4})*)")
DECISION_FILE = re.compile(r"decisions/(\d{4}-[\w-]+\.md)")


def params_comments(text: str) -> str:
    """The comments of a YAML text, each on its own line (line numbers kept)."""
    return "\n".join(m.group(1) if (m := re.search(r"(?:^|\s)#(.*)$", line)) else ""
                     for line in text.splitlines())


def headings(page: str) -> set[str]:
    text = re.sub(r"```.*?```", "", (REPO / page).read_text(), flags=re.S)
    titles = re.findall(r"^#{1,6}\s+(.+?)\s*$", text, re.M)
    return set(titles) | {t.split(":")[0] for t in titles}


def wrong_references(name: str, text: str, paths: bool) -> list[str]:
    """`name:line: what` for each citation of the text that names nothing; paths and sections only
    when `paths` (params.yaml's comments: the pages' links have their own test)."""
    files = tracked_names()
    records = {f.removeprefix("docs/decisions/") for f in files if f.startswith("docs/decisions/")}
    wrong = []
    def at(m, what):
        wrong.append(f"{name}:{text.count(chr(10), 0, m.start()) + 1}: {what}")
    for m in REPO_PATH.finditer(text) if paths else ():
        path = m.group(0).rstrip("./")
        if "<" in path or "{" in path:
            continue
        if "*" in path:
            if len(fnmatch.filter(files, path)) != 1:
                at(m, f"{path} matches {len(fnmatch.filter(files, path))} files, not one")
        elif path not in files and not any(f.startswith(path + "/") for f in files):
            at(m, f"{path} is not in the repository")
    for m in MODULE.finditer(text) if paths else ():
        if not any(f == "src/tactilepipe/" + m.group(0) or "/" not in m.group(0) and f.startswith("src/")
                   and f.endswith("/" + m.group(0)) for f in files):
            at(m, f"{m.group(0)} is no module of src/tactilepipe/")
    for m in SECTION.finditer(text) if paths else ():
        if m.group(1) in files and m.group(2) not in headings(m.group(1)):
            at(m, f'{m.group(1)} has no heading "{m.group(2)}"')
    for m in DECISION.finditer(text):
        for number in re.findall(r"\d{4}", m.group(1)):
            if not any(r.startswith(number + "-") for r in records):
                at(m, f"decision {number} has no record in docs/decisions/")
    for m in DECISION_FILE.finditer(text):
        if m.group(1) not in records:
            at(m, f"docs/decisions/{m.group(1)} does not exist")
    return wrong


def test_the_citations_of_params_yaml_and_the_pages_exist():
    wrong = wrong_references("params.yaml", params_comments((REPO / "params.yaml").read_text()), paths=True)
    for page in [REPO / p for p in DOC_PAGES] + sorted((REPO / "docs").glob("*.md")):
        wrong += wrong_references(str(page.relative_to(REPO)), page.read_text(), paths=False)
    assert not wrong, "citations of what does not exist:\n" + "\n".join(wrong)


def test_the_citation_check_finds_a_missing_path_decision_and_heading():
    text = params_comments(
        "a: 1  # see docs/no_such_page.md and src/tactilepipe/cli/, tool/no_such.py, tool/data/witness.py\n"
        "b: 2  # decisions 0025 and 0999; docs/decisions/0008-*.md, docs/decisions/0033-wrong-slug.md\n"
        'c: 3  # docs/robustness.md, "No such heading"; docs/robustness.md "Volume labels"\n'
        'd: 4  # docs/reproducibility.md, "Repeats and width" (its heading before the colon)\n')
    assert wrong_references("p", text, paths=True) == [
        "p:1: docs/no_such_page.md is not in the repository",
        "p:2: docs/decisions/0033-wrong-slug.md is not in the repository",
        "p:1: tool/no_such.py is no module of src/tactilepipe/",
        'p:3: docs/robustness.md has no heading "No such heading"',
        "p:2: decision 0999 has no record in docs/decisions/",
        "p:2: docs/decisions/0033-wrong-slug.md does not exist"]


class OtherThan(tuple):
    """Every module of tactilepipe outside the packages named."""


# Who may not import whom. A name is a package of tactilepipe with everything under it
# ("tool.formats": tool/formats/*.py; "__main__": the module `python -m tactilepipe` runs).
LAYER_RULES = [
    # importers                                          may not import                          rule
    (("core",),                                          OtherThan(("core",)),
     "core is the base: it imports no other tactilepipe package"),
    (("tool.formats",),                                  ("tool.data", "tool.model", "tool.report"),
     "the raw trial formats come before the data, models and reports made from them"),
    (("tool", "volume", "drift", "papillarray", "rig"),  ("pipeline", "cli"),
     "study and rig code serve the workflow glue (pipeline) and the command line (cli), never the reverse"),
    (("pipeline",),                                      ("tool", "volume", "drift", "papillarray", "rig"),
     "the workflow glue knows no study: it reads each through its contract (tactilepipe/studies.py)"),
    # __main__ is the command line's entry point: it runs cli.main
    (OtherThan(("cli", "__main__")),                     ("cli",),
     "only the command line imports the command line"),
]


def library_modules() -> list[str]:
    """Every module of src/tactilepipe by its dotted name (a package by its __init__.py)."""
    src = REPO / "src"
    names = []
    for path in sorted((src / PACKAGE).rglob("*.py")):
        parts = path.relative_to(src).with_suffix("").parts
        names.append(".".join(parts[:-1] if parts[-1] == "__init__" else parts))
    return names


def import_graph() -> dict[str, set[str]]:
    """module -> the tactilepipe modules it imports, at module level or inside functions."""
    return {m: set(module_imports(m)) - {m} for m in library_modules()}


def _covers(packages: tuple[str, ...], module: str) -> bool:
    name = module.removeprefix(PACKAGE).removeprefix(".")
    inside = any(name == p or name.startswith(p + ".") for p in packages)
    return not inside if isinstance(packages, OtherThan) else inside


def layer_violations(graph: dict[str, set[str]]) -> list[str]:
    return [f"{importer} imports {imported}: {rule}"
            for importer, imports in sorted(graph.items()) for imported in sorted(imports)
            for importers, forbidden, rule in LAYER_RULES
            if _covers(importers, importer) and _covers(forbidden, imported)]


def import_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The import cycles, one for each import that closes a cycle in a depth-first walk, each as
    [a, b, ..., a]."""
    cycles, state, path = [], {}, []

    def visit(module):
        state[module] = "open"
        path.append(module)
        for imported in sorted(graph.get(module, ())):
            if state.get(imported) == "open":
                cycles.append(path[path.index(imported):] + [imported])
            elif imported not in state:
                visit(imported)
        path.pop()
        state[module] = "done"

    for module in sorted(graph):
        if module not in state:
            visit(module)
    return cycles


def test_no_import_cycle_among_library_modules():
    cycles = import_cycles(import_graph())
    assert not cycles, "import cycles:\n" + "\n".join(" -> ".join(c) for c in cycles)


def test_packages_import_each_other_one_way_only():
    violations = layer_violations(import_graph())
    assert not violations, "\n".join(violations)


def test_the_import_audits_find_what_they_look_for():
    graph = {"tactilepipe.core.a": {"tactilepipe.tool.b"}, "tactilepipe.tool.b": {"tactilepipe.core.a"},
             "tactilepipe.tool.formats.c": {"tactilepipe.tool.data.d"}, "tactilepipe.__main__": {"tactilepipe.cli.e"}}
    assert import_cycles(graph) == [["tactilepipe.core.a", "tactilepipe.tool.b", "tactilepipe.core.a"]]
    assert layer_violations(graph) == [
        f"tactilepipe.core.a imports tactilepipe.tool.b: {LAYER_RULES[0][2]}",
        f"tactilepipe.tool.formats.c imports tactilepipe.tool.data.d: {LAYER_RULES[1][2]}"]


def test_no_two_test_files_share_a_name():
    # the test folders are not packages: pytest imports each file by its bare name, so a second
    # file of the same name fails collection of the whole suite
    seen = {}
    for path in sorted((REPO / "tests").rglob("test_*.py")):
        seen.setdefault(path.name, []).append(str(path.relative_to(REPO)))
    assert not {n: ps for n, ps in seen.items() if len(ps) > 1}


def test_library_modules_are_short():
    long = {str(p.relative_to(REPO)): n for p in (REPO / "src").rglob("*.py")
            if (n := len(p.read_text().splitlines())) > 400}
    assert not long, f"modules over 400 lines: {long}"


def test_the_workflow_only_wires_and_names_each_snakemake_internal_it_uses():
    """common.smk stays wiring (its logic is library code), and every Snakemake internal the
    workflow reaches for is in the decision that says which upstream change it waits for."""
    common = REPO / "workflow/rules/common.smk"
    assert len(common.read_text().splitlines()) <= 200
    decision = (REPO / "docs/decisions/0028-sessions-as-data-and-snakemake-internals.md").read_text()
    used = set()
    for path in [REPO / "Snakefile", *(REPO / "workflow/rules").glob("*.smk"), *(REPO / "workflow/scripts").glob("*.py")]:
        used |= set(re.findall(r"\bworkflow\.(?:iocache\.\w+|dryrun|dag\.\w+|dag)\b|\b_(?:workflow|prepare_dag|build_dag)\b"
                               r"|\bthreading\.Timer\b", path.read_text()))
    assert used, "the audit found no internal at all: its pattern no longer matches the workflow's code"
    missing = sorted(u for u in used if u not in decision)
    assert not missing, f"Snakemake internals used but not named in decision 0028: {missing}"


def test_nothing_points_outside_the_repository():
    hits = [f"{name}:{text[:m.start()].count(chr(10)) + 1}: {m.group(0)}"
            for name, text in tracked_text_files() for rx in OUTSIDE for m in rx.finditer(text)]
    assert not hits, hits


def test_the_declared_dependencies_admit_the_locked_versions():
    import tomllib
    from packaging.requirements import Requirement
    from packaging.utils import canonicalize_name
    declared = [Requirement(r) for r in tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["dependencies"]]
    locked = {}
    for line in (REPO / "requirements.txt").read_text().splitlines():
        if "==" in line and not line.startswith("#"):
            name, version = line.split("==")
            locked[canonicalize_name(name)] = version.strip()
    assert declared, "pyproject.toml declares no dependencies: `pip install .` would give a package that cannot import"
    for req in declared:
        version = locked.get(canonicalize_name(req.name))
        assert version is not None, f"{req.name}: declared in pyproject.toml, not locked in requirements.txt"
        assert req.specifier.contains(version, prereleases=True), f"{req}: the lock has {version}"


# Where Python that may read a shared checkpoint lives. A test that deliberately writes a pickle
# carrying code (to show it is refused) may load it unrestricted once, to prove the payload live.
CODE_ROOTS = ("src", "benchmarks", "studies", "workflow", "tests")
CRAFTS_MALICIOUS_PICKLES = {"tests/robustness/test_bounded_inputs.py"}


def unrestricted_torch_loads(source: str, name: str) -> list[str]:
    """``name:line`` of each ``torch.load(...)`` call without ``weights_only=True``: without it a
    checkpoint is a pickle, and loading one from a shared results folder runs whatever it names."""
    hits = []
    for node in ast.walk(ast.parse(source, name)):
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "load"
                and isinstance(node.func.value, ast.Name) and node.func.value.id == "torch"):
            safe = any(k.arg == "weights_only" and isinstance(k.value, ast.Constant) and k.value.value is True
                       for k in node.keywords)
            if not safe:
                hits.append(f"{name}:{node.lineno}")
    return hits


def test_every_torch_load_is_restricted_to_weights():
    hits, scanned = [], 0
    for root in CODE_ROOTS:
        for path in sorted((REPO / root).rglob("*.py")):
            name = path.relative_to(REPO).as_posix()
            if ".venv" in path.parts or name in CRAFTS_MALICIOUS_PICKLES:
                continue
            scanned += 1
            hits += unrestricted_torch_loads(path.read_text(), name)
    for path in [REPO / "Snakefile", *(REPO / "workflow").rglob("*.smk")]:     # not Python to ast: by text
        hits += [f"{path.relative_to(REPO)}: torch.load" for _ in re.findall(r"\btorch\.load\(", path.read_text())]
    assert scanned > 100, "the scan found almost no Python: its roots moved"
    assert not hits, f"torch.load without weights_only=True (a checkpoint's pickle could run code): {hits}"


def test_the_torch_load_scan_finds_what_it_looks_for():
    source = ("import torch\na = torch.load(p, weights_only=True)\nb = torch.load(p)\n"
              "c = torch.load(p, weights_only=False)\nd = torch.load(p, weights_only=flag)\n")
    assert unrestricted_torch_loads(source, "x.py") == ["x.py:3", "x.py:4", "x.py:5"]
