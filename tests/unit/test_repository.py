"""The repository as a newcomer meets it: a short README whose links and promised places exist,
short library modules, and no pointer to material outside the repository."""

from __future__ import annotations

import re
import subprocess

import pytest

from support.project import REPO

LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")
# spelled in two parts so that this file does not match itself
OUTSIDE = [re.compile(p) for p in (r"\.\./" + "shared", "REFERENCE" + r"\.md", r"\b[Ii]ssue" + r" #?\d+")]


def tracked_text_files():
    try:
        names = subprocess.run(["git", "ls-files"], cwd=REPO, capture_output=True, text=True,
                               check=True).stdout.split()
    except (OSError, subprocess.CalledProcessError):
        pytest.skip("not a git checkout")
    for name in names:
        path = REPO / name
        if path.suffix in {".png", ".pdf", ".npy", ".parquet", ".pt", ".bag", ".jpg"} or not path.is_file():
            continue
        try:
            yield name, path.read_text()
        except UnicodeDecodeError:
            continue


def test_readme_is_short():
    assert len((REPO / "README.md").read_bytes()) <= 8000


def test_links_of_the_readme_and_docs_exist():
    for page in [REPO / "README.md", *(REPO / "docs").rglob("*.md")]:
        for target in LINK.findall(page.read_text()):
            if "://" not in target and not target.startswith("mailto:"):
                assert (page.parent / target).exists(), f"{page.relative_to(REPO)} links to missing {target}"


def test_the_places_the_readme_promises_exist():
    src = REPO / "src" / "tactilepipe"
    assert "class ToolFrames" in (src / "tool" / "data" / "loader.py").read_text()
    assert re.search(r"^VARIANTS\b", (src / "tool" / "model" / "network.py").read_text(), re.M)
    figures = list((src / "tool" / "report").glob("figures_*.py"))
    assert figures and all("savefig" in f.read_text() or "save_figure" in f.read_text() for f in figures)


def test_library_modules_are_short():
    long = {str(p.relative_to(REPO)): n for p in (REPO / "src").rglob("*.py")
            if (n := len(p.read_text().splitlines())) > 400}
    assert not long, f"modules over 400 lines: {long}"


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
