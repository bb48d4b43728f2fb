"""The reference documentation points at what exists and carries no history.

Reference docs are README.md and every Markdown file under docs/ (the decision records
included). Each relative link must name an existing file; each path or dotted module name
of this repository written in backticks must exist; and none may hold a date or a
commit-hash-like token: history lives in CHANGELOG.md and in git.
"""
from __future__ import annotations

import ast
import io
import re
import tokenize
from functools import cache
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
REFERENCE_DOCS = sorted([ROOT / "README.md", *(ROOT / "docs").rglob("*.md")])
TEST_FILES = sorted(p for p in (ROOT / "tests").rglob("*.py") if p.name != "test_docs.py")

LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")
CODE = re.compile(r"`([^`\n]+)`")
# A path of this repository: starts with one of its top-level folders.
REPO_PATH = re.compile(r"^(?:docs|pipeline|geometry|bench|tests|tools|cases)/[\w./-]*\w$")
# A dotted name in one of the Python packages: pipeline.fe.solve, geometry.curved, ...
MODULE_NAME = re.compile(r"(?<![\w./-])((?:pipeline|geometry|bench)(?:\.[A-Za-z_]\w*)+)")
# A file name, not a module: results/bench/bench.json, bench.png.
FILE_NAME = re.compile(r"\.(?:csv|png|jsonl?|md|py|msh|vtu|vtp|toml|html|pdf|txt|sh|inp)$")
# A module's short name and one of its names: errorbar.verdict_against, meshing.Mesher.
SHORT_NAME = re.compile(r"^([a-z_][a-z0-9_]*)\.([A-Za-z_]\w*)")
# Dotted names of other libraries, objects and results.json keys, not of this repository.
FOREIGN = frozenset({"dolfinx", "fem", "gmsh", "gmshio", "ksp", "mesh", "w", "fe", "np", "ufl", "importlib",
                     "pipeline", "geometry", "bench"})
MODULES_BY_STEM: dict[str, list[Path]] = {}
for _source in sorted(p for top in ("pipeline", "geometry", "bench") for p in (ROOT / top).rglob("*.py")):
    MODULES_BY_STEM.setdefault(_source.stem, []).append(_source)
# A commit hash: seven or more hex digits with a letter and a digit, or seven digits
# standing alone (figures in these docs carry a decimal point or a thin space).
COMMIT = re.compile(r"(?<![.\d])\b(?=[0-9a-f]*[a-f])(?=[0-9a-f]*[0-9])[0-9a-f]{7,40}\b(?![-+]\d)"
                    r"|(?<![\d.,^])\b\d{7}\b(?![.,]\d)")
DATE = re.compile(r"\b(?:19|20)\d\d-(?:0[1-9]|1[0-2])-(?:0[1-9]|[12]\d|3[01])\b")


def _rel(path: Path) -> str:
    return str(path.relative_to(ROOT))


@cache
def _top_level_names(source: Path, imported: bool) -> frozenset[str]:
    """The names a module defines at its top level, and those it imports when
    ``imported`` (a package's ``__init__`` re-exports; a module's imports are not its own)."""
    names = set()
    for node in ast.parse(source.read_text(encoding="utf-8")).body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            names |= {t.id for t in targets if isinstance(t, ast.Name)}
        elif imported and isinstance(node, (ast.Import, ast.ImportFrom)):
            names |= {(a.asname or a.name).split(".")[0] for a in node.names}
    return frozenset(names)


def _module_exists(dotted: str) -> bool:
    """True when the dotted name is a module of the repository, or a module followed by a
    name it defines (and anything below that name): ``pipeline.fe.solve.solve`` passes;
    ``pipeline.solve.stress``, ``pipeline.fe.stress`` and ``pipeline.fe.solve.stress``
    (defined in elasticity, only imported by solve) do not."""
    parts = dotted.split(".")
    path = ROOT / parts[0]
    for i, part in enumerate(parts[1:], start=1):
        if (path / part).is_dir() and (path / part / "__init__.py").is_file():
            path = path / part
        elif (path / f"{part}.py").is_file():
            path = path / part
            if i + 1 == len(parts):
                return True
            return parts[i + 1] in _top_level_names(path.with_suffix(".py"), imported=False)
        else:
            return part in _top_level_names(path / "__init__.py", imported=True)
    return True


def _prose_of(test_file: Path) -> str:
    """The comments and docstrings of a Python file (its test data may hold dates)."""
    text = test_file.read_text(encoding="utf-8")
    pieces = [tok.string for tok in tokenize.generate_tokens(io.StringIO(text).readline)
              if tok.type == tokenize.COMMENT]
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, (ast.Module, ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            pieces.append(ast.get_docstring(node) or "")
    return "\n".join(pieces)


def _code_spans(text: str) -> list[str]:
    return [m.group(1).strip() for m in CODE.finditer(text)]


@pytest.mark.parametrize("doc", REFERENCE_DOCS, ids=_rel)
def test_relative_links_resolve(doc: Path):
    broken = []
    for target in LINK.findall(doc.read_text(encoding="utf-8")):
        if re.match(r"^[a-z]+:", target) or target.startswith("#"):
            continue  # a URL or an anchor in the same file
        path = (doc.parent / target.split("#", 1)[0]).resolve()
        if not path.exists():
            broken.append(target)
    assert broken == [], f"{_rel(doc)}: links to missing files {broken}"


@pytest.mark.parametrize("doc", REFERENCE_DOCS, ids=_rel)
def test_named_paths_and_modules_exist(doc: Path):
    missing = []
    for span in _code_spans(doc.read_text(encoding="utf-8")):
        for word in span.split():
            word = word.strip("(),;:")
            if REPO_PATH.match(word) and not (ROOT / word).exists():
                missing.append(word)
        missing += [name for name in MODULE_NAME.findall(span)
                    if not FILE_NAME.search(name) and not _module_exists(name)]
        short = SHORT_NAME.match(span)
        if short and not FILE_NAME.search(span) and short.group(1) not in FOREIGN:
            stem, name = short.groups()
            if (ROOT / "pipeline" / stem / "__init__.py").is_file():
                known = _module_exists(f"pipeline.{short.group(0)}")
            else:
                known = any(name in _top_level_names(m, imported=False)
                            for m in MODULES_BY_STEM.get(stem, []))
            if not known:
                missing.append(short.group(0))
    assert missing == [], f"{_rel(doc)}: names what the repository does not have {missing}"


# A file named with the functions or classes it holds: `pipeline/analysis/run.py` (`run`, ...)
# or, in a package's row, `run.py` (`run`): each name in the parentheses must be defined there.
FILE_WITH_NAMES = re.compile(r"`([\w/]+)\.py` \(([^)]*)\)")
NAME_SPAN = re.compile(r"`([A-Za-z_]\w*)`")


def _defined_in(file_span: str, name: str) -> bool:
    """Whether ``name`` is defined at the top level of the file a doc names as
    ``file_span`` (a path from the repository's root, or a file's stem)."""
    path = ROOT / f"{file_span}.py"
    candidates = [path] if path.is_file() else MODULES_BY_STEM.get(Path(file_span).name, [])
    return any(name in _top_level_names(c, imported=False) for c in candidates)


@pytest.mark.parametrize("doc", REFERENCE_DOCS, ids=_rel)
def test_functions_named_beside_their_files_are_there(doc: Path):
    """docs/architecture.md puts names beside files: `pipeline/analysis/run.py` (`run`)."""
    wrong = [f"{f}.py: {name}" for f, inside in FILE_WITH_NAMES.findall(doc.read_text(encoding="utf-8"))
             for name in NAME_SPAN.findall(inside) if not name.isupper() and not _defined_in(f, name)]
    assert wrong == [], f"{_rel(doc)}: names a function where the file does not define it {wrong}"


@pytest.mark.parametrize("doc", REFERENCE_DOCS, ids=_rel)
def test_reference_docs_carry_no_dates_or_commits(doc: Path):
    text = doc.read_text(encoding="utf-8")
    found = sorted(set(DATE.findall(text)) | set(COMMIT.findall(text)))
    assert found == [], f"{_rel(doc)}: history belongs in CHANGELOG.md and git, found {found}"


@pytest.mark.parametrize("test_file", TEST_FILES, ids=_rel)
def test_tests_name_existing_modules_and_no_history(test_file: Path):
    text = _prose_of(test_file)
    stale = [name for name in MODULE_NAME.findall(text) if not _module_exists(name)]
    history = sorted(set(DATE.findall(text)) | set(COMMIT.findall(text)))
    assert stale == [] and history == [], f"{_rel(test_file)}: {stale} {history}"


def test_the_checks_catch_what_they_are_for():
    """The patterns find a date, a hash, a stale module and a missing path, and pass the
    ordinary figures of these docs (tolerances, decimals, hex-letter words)."""
    assert DATE.findall("measured 2026-11-25") == ["2026-11-25"]
    assert COMMIT.findall("at 8976308 and ed18b99") == ["8976308", "ed18b99"]
    assert COMMIT.findall("rtol 1e-8, 113.82 MPa, 113.767407718 MPa, deadbeef") == []
    assert not _module_exists("pipeline.solve.stress")
    assert not _module_exists("pipeline.fe.stress")
    assert not _module_exists("pipeline.fe.solve.stress")
    assert _module_exists("pipeline.fe.elasticity.von_mises") or _module_exists("pipeline.fe.elasticity")
    assert COMMIT.findall("4.21991607979353e-05") == []
    assert not REPO_PATH.match("results.json") and REPO_PATH.match("docs/design.md")
    assert "errorbar" in MODULES_BY_STEM and "sweepresults" not in MODULES_BY_STEM
    assert _defined_in("pipeline/post/errorbar", "estimate_levels") and not _defined_in("pipeline/analysis/run",
                                                                                       "estimate_levels")
    assert FILE_WITH_NAMES.findall("`pipeline/analysis/meshes.py` (`estimate_levels`)") == [
        ("pipeline/analysis/meshes", "`estimate_levels`")]
