"""The house's rules, checked on the source (issue 14): imports only go down the layers,
no package reaches into another's private names, and no function in reconstruct/ or
acquire/ is over 80 lines."""

from __future__ import annotations

import ast
from pathlib import Path

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
# kernels excepted: a pipeline is a short list of named steps (issue 14).
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
