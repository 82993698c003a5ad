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
