"""The type stubs shipped with the package name what the module has, and nothing else."""

import ast
import inspect
from pathlib import Path

import moe_touch as mt

STUB = Path(__file__).resolve().parents[1] / "moe_touch.pyi"


def test_the_stubs_match_the_module():
    tree = ast.parse(STUB.read_text())
    stubbed = {}
    for node in tree.body:
        if isinstance(node, ast.ClassDef):
            stubbed[node.name] = {
                n.name for n in node.body if isinstance(n, ast.FunctionDef)
            } - {"__init__"}
        elif isinstance(node, ast.FunctionDef):
            stubbed[node.name] = None
    public = {n for n in dir(mt) if not n.startswith("_") and not inspect.ismodule(getattr(mt, n))}
    assert public == set(stubbed), (public ^ set(stubbed))
    for name, members in stubbed.items():
        if members is None:
            continue
        cls = getattr(mt, name)
        missing = {m for m in members if not hasattr(cls, m)}
        assert not missing, (name, missing)
        real = {m for m in vars(cls) if not m.startswith("_")}
        assert real <= members, (name, real - members)


def stub_parameters(fn):
    args = fn.args
    names = [a.arg for a in args.posonlyargs + args.args + args.kwonlyargs]
    return [n for n in names if n not in ("self", "cls")]


def test_the_stub_signatures_name_the_real_parameters():
    """Every stubbed function, constructor and method whose signature the module exposes takes
    the parameters the stub names, in its order (special methods keep Python's own names)."""
    tree = ast.parse(STUB.read_text())
    checked = 0
    for node in tree.body:
        if isinstance(node, ast.FunctionDef):
            targets = [(getattr(mt, node.name), node)]
        elif isinstance(node, ast.ClassDef):
            cls = getattr(mt, node.name)
            targets = [
                (cls if f.name == "__init__" else getattr(cls, f.name), f)
                for f in node.body
                if isinstance(f, ast.FunctionDef)
                and (f.name == "__init__" or not f.name.startswith("__"))
                and not any(isinstance(d, ast.Name) and d.id == "property" for d in f.decorator_list)
            ]
        else:
            continue
        for real, stub in targets:
            try:
                signature = inspect.signature(real)
            except (TypeError, ValueError):
                continue
            names = [p for p in signature.parameters if p not in ("self", "cls", "$self", "$cls")]
            assert names == stub_parameters(stub), (node.name, stub.name, names)
            checked += 1
    assert checked >= 15, checked
