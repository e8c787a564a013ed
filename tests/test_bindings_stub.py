"""The type stub ``gfcs/_core.pyi`` documents every public name of the compiled module, and nothing more."""

from __future__ import annotations

import ast
import inspect
from pathlib import Path

import gfcs
import pytest
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


def _stub_functions():
    """{(class or None, name): ast.FunctionDef} of the stub (overloads: the last one)."""
    tree = ast.parse(STUB.read_text())
    out = {}
    for node in tree.body:
        if isinstance(node, ast.FunctionDef):
            out[(None, node.name)] = node
        elif isinstance(node, ast.ClassDef):
            for f in node.body:
                if isinstance(f, ast.FunctionDef):
                    out[(node.name, f.name)] = f
    return out


def _stub_parameters(node, method):
    """[(name, kind, has_default)] of a stub function (``self`` dropped for methods)."""
    a = node.args
    positional = a.posonlyargs + a.args
    defaults = [False] * (len(positional) - len(a.defaults)) + [True] * len(a.defaults)
    out = [(p.arg, "positional", d) for p, d in zip(positional, defaults)]
    if method and out and out[0][0] in ("self", "cls"):
        out = out[1:]
    if a.vararg:
        out.append((a.vararg.arg, "*", False))
    out += [(p.arg, "keyword", d is not None) for p, d in zip(a.kwonlyargs, a.kw_defaults)]
    if a.kwarg:
        out.append((a.kwarg.arg, "**", False))
    return out


def _runtime_parameters(obj):
    kinds = {inspect.Parameter.VAR_POSITIONAL: "*", inspect.Parameter.VAR_KEYWORD: "**",
             inspect.Parameter.KEYWORD_ONLY: "keyword"}
    params = [p for p in inspect.signature(obj).parameters.values() if p.name not in ("self", "cls")]
    return [(p.name, kinds.get(p.kind, "positional"), p.default is not inspect.Parameter.empty
             and p.kind not in (inspect.Parameter.VAR_POSITIONAL, inspect.Parameter.VAR_KEYWORD))
            for p in params]


def _callables():
    for name, obj in vars(_core).items():
        if inspect.isbuiltin(obj) and not name.startswith("_"):
            yield None, name, obj
        elif inspect.isclass(obj) and not issubclass(obj, BaseException):
            for m, f in vars(obj).items():
                if not m.startswith("_") and callable(f):
                    yield name, m, f


def test_every_signature_matches_its_stub():
    """Parameter names, order, kinds and which have defaults agree between the module and the stub."""
    stub = _stub_functions()
    checked = 0
    for cls, name, obj in _callables():
        try:
            runtime = _runtime_parameters(obj)
        except ValueError:  # no text signature (a classmethod without one): nothing to compare
            continue
        assert (cls, name) in stub, f"{cls}.{name} missing from the stub"
        assert _stub_parameters(stub[(cls, name)], cls is not None) == runtime, f"{cls}.{name}"
        checked += 1
    assert checked > 40


def test_rollout_options_are_defined_once():
    """The stub's option TypedDicts, the core's defaults and RolloutSettings name the same options, and the
    settings' defaults are the core's."""
    import dataclasses

    from gfcs.planning import RolloutSettings

    tree = ast.parse(STUB.read_text())
    typed = {n.name: [f.target.id for f in n.body if isinstance(f, ast.AnnAssign)]
             for n in tree.body if isinstance(n, ast.ClassDef) and n.name in ("RolloutOptions", "SequenceOptions")}
    defaults = _core.rollout_option_defaults()
    assert set(typed["RolloutOptions"]) | set(typed["SequenceOptions"]) == set(defaults)
    fields = {f.name: f.default for f in dataclasses.fields(RolloutSettings)}
    assert set(fields) - {"limit_hold_off"} == set(defaults)
    assert {k: fields[k] for k in defaults} == defaults
    # Fabric.rollout takes exactly RolloutOptions; a sequence option is refused there, naming it
    fabric = gfcs.Fabric(gfcs.Robot.panda())
    q = [0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.8]
    fabric.rollout(q, None, q, record=False, **{k: defaults[k] for k in typed["RolloutOptions"]})
    for k in typed["SequenceOptions"]:
        with pytest.raises(gfcs.InvalidValueError, match=k):
            fabric.rollout(q, None, q, **{k: defaults[k]})
    with pytest.raises(gfcs.InvalidValueError, match="not an option of Fabric.evaluate"):
        fabric.evaluate(q, None, q, [q], tolerance=0.1)
    with pytest.raises(gfcs.InvalidValueError, match="dt"):
        fabric.rollout_sequence(q, None, [q], q, dt="fast")
