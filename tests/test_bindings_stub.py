"""The type stub ``gfcs/_core.pyi`` documents every public name of the compiled module, and nothing more."""

from __future__ import annotations

import ast
import inspect
from pathlib import Path

import gfcs
from gfcs import _core

STUB = Path(gfcs.__file__).with_name("_core.pyi")


def stub_names():
    tree = ast.parse(STUB.read_text())
    top, classes = set(), {}
    for node in tree.body:
        if isinstance(node, ast.ClassDef):
            top.add(node.name)
            classes[node.name] = {n.name for n in node.body if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))}
        elif isinstance(node, ast.FunctionDef):
            top.add(node.name)
        elif isinstance(node, ast.Assign):
            top.update(t.id for t in node.targets if isinstance(t, ast.Name))
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            top.add(node.target.id)
    return top, classes


def test_stub_and_py_typed_exist():
    assert STUB.is_file()
    assert STUB.with_name("py.typed").is_file()


def test_every_public_name_is_in_the_stub():
    top, classes = stub_names()
    public = {n for n in dir(_core) if not n.startswith("__") or n == "__version__"}
    public -= {"_core"}
    missing = public - top
    assert not missing, f"missing from _core.pyi: {sorted(missing)}"
    for name, obj in vars(_core).items():
        if inspect.isclass(obj) and not issubclass(obj, BaseException):
            members = {m for m in vars(obj) if not m.startswith("_")}
            assert members <= classes[name], f"{name}: {sorted(members - classes[name])} not in the stub"
            extra = {m for m in classes[name] if not m.startswith("_")} - members
            assert not extra, f"{name}: stub lists {sorted(extra)} which the class lacks"
