"""The house's rules, checked on the source: imports only go down the layers, no package
reaches into another's private names, no function in reconstruct/ or acquire/ is over 80
lines, no import circle between modules; every package has at most 8 modules at its top
level and its rooms (sub-packages) name their public API; inside acquire/ and
reconstruct/, a room per method above the shared rooms: no upward or sideways import; in
them and in scanamp/, no circle between rooms and no private name across rooms."""

from __future__ import annotations

import ast
import importlib
from collections import defaultdict
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("core", "procgen", "simulate", "acquire", "data_synth", "reconstruct", "scanamp")
# what each package may import (besides itself): the layering of README.md
ALLOWED = {
    "core": set(),
    "procgen": {"core"},
    "simulate": {"core", "procgen"},
    "acquire": {"core", "procgen"},
    "data_synth": {"core", "procgen", "acquire"},
    "reconstruct": {"core", "procgen", "acquire"},  # never data_synth: it runs on real data
    "scanamp": {"core", "procgen", "simulate", "acquire", "data_synth", "reconstruct"},
}


def _sources():
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            yield pkg, path, ast.parse(path.read_text(), filename=str(path))


def _imports(tree):
    """(module, [names]) of every absolute import, wherever it is (functions included)."""
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                yield a.name, []
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            yield node.module, [a.name for a in node.names]


SOURCES = list(_sources())


def test_imports_only_go_down():
    upward = []
    for pkg, path, tree in SOURCES:
        for module, _ in _imports(tree):
            top = module.split(".")[0]
            if top in PACKAGES and top != pkg and top not in ALLOWED[pkg]:
                upward.append(f"{path.relative_to(ROOT)} imports {module}")
    assert not upward, "\n".join(upward)


def test_no_package_imports_another_packages_private_names():
    private = []
    for pkg, path, tree in SOURCES:
        for module, names in _imports(tree):
            top = module.split(".")[0]
            if top not in PACKAGES or top == pkg:
                continue
            bad = [p for p in module.split(".")[1:] if p.startswith("_")]
            bad += [n for n in names if n.startswith("_")]
            if bad:
                private.append(f"{path.relative_to(ROOT)}: from {module} import {names}")
    assert not private, "\n".join(private)


def _is_numba_kernel(fn: ast.FunctionDef) -> bool:
    for d in fn.decorator_list:
        target = d.func if isinstance(d, ast.Call) else d
        name = target.attr if isinstance(target, ast.Attribute) else getattr(target, "id", "")
        if name in ("njit", "jit", "vectorize", "guvectorize", "stencil"):
            return True
    return False


# No function in reconstruct/ or acquire/ over this many lines (docstring aside), numba
# kernels excepted: a pipeline is a short list of named steps.
LONG_FUNCTION_LIMIT = 80


def _body_lines(fn) -> int:
    """Lines of a function without its docstring."""
    body = fn.body
    if body and isinstance(body[0], ast.Expr) and isinstance(getattr(body[0], "value", None),
                                                             ast.Constant) \
            and isinstance(body[0].value.value, str) and len(body) > 1:
        body = body[1:]
    return fn.end_lineno - body[0].lineno + 2  # + the signature's line


def _long_functions() -> dict[str, int]:
    found = {}
    for pkg, path, tree in SOURCES:
        if pkg not in ("reconstruct", "acquire"):
            continue
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and \
                    not _is_numba_kernel(node):
                n = _body_lines(node)
                if n > LONG_FUNCTION_LIMIT:
                    found[f"{path.relative_to(ROOT)}::{node.name}"] = n
    return found


def test_no_long_functions_in_reconstruct_and_acquire():
    found = _long_functions()
    assert not found, f"functions over {LONG_FUNCTION_LIMIT} lines (split them): {found}"


# -- rooms: a sub-package of a package ----------------------------------------------------

ROOMED = ("acquire", "reconstruct")
# the packages whose rooms are checked for circles and private names across them
# (packages with no sub-package yet are checked module by module, below)
ROOM_RULES = ROOMED + ("scanamp",)
# one room per acquisition method; everything else in the package is shared by them
METHOD_ROOMS = {"laser", "stereo", "sfm", "scans", "lidar"}
MAX_TOP_LEVEL_MODULES = 8


def _room(pkg: str, path: Path) -> str:
    """The room of a source file: its sub-package, or its module when at the top level."""
    rel = path.relative_to(ROOT / pkg)
    return rel.parts[0] if len(rel.parts) > 1 else rel.stem


def _room_of_module(pkg: str, module: str) -> str | None:
    parts = module.split(".")
    if parts[0] != pkg or len(parts) < 2:
        return None
    return parts[1]


def _room_imports():
    """{(pkg, room): {room it imports: [where]}} over every import, lazy ones included."""
    edges = defaultdict(lambda: defaultdict(list))
    for pkg, path, tree in SOURCES:
        if path.name == "__init__.py" and path.parent == ROOT / pkg:
            continue
        here = _room(pkg, path)
        for node in ast.walk(tree):
            mods = []
            if isinstance(node, ast.Import):
                mods = [(a.name, []) for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                mods = [(node.module, [a.name for a in node.names])]
            for module, names in mods:
                there = _room_of_module(pkg, module)
                if there is None and module == pkg:       # from acquire import render
                    for n in names:
                        edges[(pkg, here)][n].append((path, module, [n]))
                elif there is not None and there != here:
                    edges[(pkg, here)][there].append((path, module, names))
    return edges


ROOM_EDGES = _room_imports()


def test_shared_rooms_never_import_method_rooms_and_methods_never_each_other():
    bad = []
    for (pkg, here), targets in ROOM_EDGES.items():
        for there, where in targets.items():
            if pkg in ROOMED and there in METHOD_ROOMS:
                kind = "method room" if here in METHOD_ROOMS else "shared room"
                for path, module, _ in where:
                    bad.append(f"{path.relative_to(ROOT)} ({kind} {here}) imports {module}")
    assert not bad, "\n".join(bad)


def test_rooms_form_no_circle():
    cycles = []
    for pkg in ROOM_RULES:
        graph = {here: set(t) for (p, here), t in ROOM_EDGES.items() if p == pkg}
        state = {}

        def visit(node, stack, graph=graph, state=state, pkg=pkg):
            state[node] = "open"
            for nxt in sorted(graph.get(node, ())):
                if state.get(nxt) == "open":
                    cycles.append(f"{pkg}: " + " -> ".join(stack[stack.index(nxt):] + [nxt]))
                elif nxt not in state:
                    visit(nxt, stack + [nxt])
            state[node] = "done"

        for node in sorted(graph):
            if node not in state:
                visit(node, [node])
    assert not cycles, "\n".join(cycles)


def test_no_private_name_across_rooms():
    private = []
    for (pkg, here), targets in ROOM_EDGES.items():
        if pkg not in ROOM_RULES:
            continue
        for there, where in targets.items():
            for path, module, names in where:
                parts = module.split(".")[1:] + names
                if there.startswith("_") or any(p.startswith("_") for p in parts):
                    private.append(f"{path.relative_to(ROOT)} ({here}): {module} {names}")
    assert not private, "\n".join(private)


def _code_rooms(pkg: str):
    """The package's sub-packages that hold code (not data folders such as studies/)."""
    for init in sorted((ROOT / pkg).glob("*/__init__.py")):
        if any(p.name != "__init__.py" for p in init.parent.glob("*.py")):
            yield init.parent


@pytest.mark.parametrize("pkg", PACKAGES)
def test_at_most_8_modules_at_every_packages_top_level(pkg):
    top = sorted(p.stem for p in (ROOT / pkg).glob("*.py")
                 if p.name not in ("__init__.py", "__main__.py"))
    assert len(top) <= MAX_TOP_LEVEL_MODULES, f"{pkg}/ has {len(top)} top-level modules: {top}"
    if pkg in ROOMED:
        assert not set(top) & METHOD_ROOMS, f"a method's module at {pkg}/'s top level: {top}"
    for room in _code_rooms(pkg):
        assert (room / "__init__.py").read_text().lstrip().startswith('"""'), \
            f"{room.relative_to(ROOT)}/__init__.py: no docstring naming the room's contents"


def _rooms():
    for pkg in PACKAGES:
        for room in _code_rooms(pkg):
            yield f"{pkg}.{room.name}"


@pytest.mark.parametrize("room", list(_rooms()))
def test_each_rooms_public_names_resolve(room):
    mod = importlib.import_module(room)
    names = getattr(mod, "__all__", None)
    assert names, f"{room}: no __all__ naming its public API"
    missing = [n for n in names if getattr(mod, n, None) is None]
    assert not missing, f"{room}: __all__ names that do not resolve: {missing}"


# -- no import circle between modules ------------------------------------------------------

def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {_module_name(path): (pkg, tree) for pkg, path, tree in SOURCES}


def _import_graph() -> dict[str, set[str]]:
    """Module -> the modules of our packages it imports, lazy imports included
    (``from a.b import c`` is an edge to ``a.b.c`` when that is a module, else to ``a.b``)."""
    def resolve(name: str) -> str | None:
        while name and name not in MODULES:
            name = name.rpartition(".")[0]
        return name or None

    graph: dict[str, set[str]] = {m: set() for m in MODULES}
    for module, (_pkg, tree) in MODULES.items():
        for name, names in _imports(tree):
            if name.split(".")[0] not in PACKAGES:
                continue
            targets = [f"{name}.{n}" if f"{name}.{n}" in MODULES else name for n in names]
            for t in targets or [name]:
                found = resolve(t)
                if found is not None and found != module:
                    graph[module].add(found)
    return graph


def _circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found = []
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            for child in children:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                    break
                if child in on_stack:
                    low[node] = min(low[node], index[child])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    comp = []
                    while True:
                        m = stack.pop()
                        on_stack.discard(m)
                        comp.append(m)
                        if m == node:
                            break
                    if len(comp) > 1:
                        found.append(sorted(comp))
    return found


CIRCLES = _circles(_import_graph())



def test_the_circle_finder_finds_a_circle():
    assert _circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _circles({"a": {"b"}, "b": set()}) == []


@pytest.mark.parametrize("pkg", PACKAGES)
def test_no_import_circle_between_a_packages_modules(pkg):
    # imports only go down the layers, so a circle never spans two packages
    mine = [c for c in CIRCLES if c[0].split(".")[0] == pkg]
    assert not mine, "import circles: " + "; ".join(" <-> ".join(c) for c in mine)
