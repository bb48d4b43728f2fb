"""The code's shape as docs/architecture.md states it: imports run down the layers (one
stated exception), no two modules import each other in a circle, no function of the
pipeline takes more than seven parameters, the bench reaches the pipeline through its
public names only, and the command line's modules stay thin. Read from the source, not
by importing it."""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
# Bottom to top (docs/architecture.md, "The packages and their layers").
LAYERS = ["geometry", "pipeline.errors", "pipeline.runtime", "pipeline.inputs", "pipeline.fe", "pipeline.post",
          "pipeline.cache", "pipeline.analysis", "pipeline.output", "pipeline.study", "pipeline.api",
          "pipeline.cli", "pipeline.__main__"]
UPWARD = {("pipeline.runtime.launch", "pipeline.cli")}  # the launcher checks the arguments once, before mpirun
MAX_PARAMETERS = 7


def module_of(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def layer_of(module: str) -> int | None:
    """The layer of a module: the longest prefix of LAYERS it falls under."""
    best = None
    for i, prefix in enumerate(LAYERS):
        if module == prefix or module.startswith(prefix + "."):
            if best is None or len(prefix) > len(LAYERS[best]):
                best = i
    return best


def imports(path: Path, tops: tuple[str, ...] = ("pipeline", "geometry", "bench")) -> list[str]:
    """The modules of this repository that a file imports (anywhere in it)."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        else:
            continue
        out += [n for n in names if n.split(".")[0] in tops]
    return out


def sources(*tops: str) -> list[Path]:
    return sorted(p for top in tops for p in (ROOT / top).rglob("*.py"))


def known(name: str, modules: set[str]) -> str | None:
    """The repository module ``name`` is (or whose member it is), if any."""
    while name and name not in modules:
        name = name.rpartition(".")[0]
    return name or None


def graph(*tops: str) -> dict[str, set[str]]:
    files = {module_of(p): p for p in sources(*tops)}
    edges = {}
    for mod, path in files.items():
        targets = {known(n, set(files)) for n in imports(path, tops)}
        edges[mod] = {t for t in targets if t and t != mod and not mod.startswith(t + ".")}
    return edges


def circles(edges: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected groups of more than one module (Tarjan)."""
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]

    def visit(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in edges.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = []
            while True:
                w = stack.pop()
                on.discard(w)
                group.append(w)
                if w == v:
                    break
            if len(group) > 1:
                out.append(sorted(group))
    for v in sorted(edges):
        if v not in index:
            visit(v)
    return out


def test_imports_run_down_the_layers():
    upward = sorted((a, b) for a, targets in graph("pipeline", "geometry").items() for b in targets
                    if layer_of(b) is not None and layer_of(a) is not None and layer_of(b) > layer_of(a)
                    and (a, ".".join(b.split(".")[:2])) not in UPWARD)
    assert upward == []


@pytest.mark.parametrize("tops", [("pipeline", "geometry"), ("bench",)])
def test_no_import_circle(tops):
    assert circles(graph(*tops)) == []


def test_no_function_takes_more_than_seven_parameters():
    long = []
    for path in sources("pipeline"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                a = node.args
                names = [x.arg for x in a.posonlyargs + a.args + a.kwonlyargs]
                n = len([x for x in names if x not in ("self", "cls")]) + bool(a.vararg) + bool(a.kwarg)
                if n > MAX_PARAMETERS:
                    long.append(f"{module_of(path)}.{node.name} ({n})")
    assert long == []


def test_the_bench_uses_only_the_public_names():
    private = sorted({f"{module_of(p)} -> {n}" for p in sources("bench") for n in imports(p, ("pipeline",))
                      if not n.startswith("pipeline.api")})
    assert private == []


def test_the_command_line_stays_thin():
    """Each module of pipeline/cli/ adds options and calls the run: at most 250 lines."""
    long = {p.name: n for p in sources("pipeline/cli") if (n := len(p.read_text().splitlines())) > 250}
    assert long == {}


def test_the_checks_catch_what_they_are_for():
    edges = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert circles(edges) == [["a", "b", "c"]]
    assert layer_of("pipeline.cli.run") > layer_of("pipeline.analysis.run") > layer_of("pipeline.fe.solve")
    assert layer_of("geometry.part") < layer_of("pipeline.errors")
