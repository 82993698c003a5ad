"""The type stubs shipped with the package name what the module has, and nothing else."""

import ast
import inspect
from pathlib import Path

import numpy as np
import pytest

import moe_touch as mt
from conftest import DATASET, EPISODE, MODEL, OCCLUDING, ROS2_EPISODE

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


def test_the_stub_classes_name_the_real_bases():
    checked = 0
    for node in ast.parse(STUB.read_text()).body:
        if isinstance(node, ast.ClassDef):
            real = [b.__name__ for b in getattr(mt, node.name).__bases__]
            assert [ast.unparse(b) for b in node.bases] == ([] if real == ["object"] else real), (
                node.name, real)
            checked += bool(node.bases)
    assert checked == 4, checked


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


# --- Annotations: every stub is annotated, names what exists, and says what the module returns --

TYPING = {"Any", "Iterator", "Literal", "Optional", "Union"}
BUILTINS = {"int", "float", "str", "bool", "list", "dict", "tuple", "Exception",
            "FileNotFoundError", "OSError", "ValueError"}


def stub_tree():
    return ast.parse(STUB.read_text())


def aliases(tree):
    """The stub's module-level type aliases (`_F64 = npt.NDArray[np.float64]`)."""
    return {n.targets[0].id: n.value for n in tree.body
            if isinstance(n, ast.Assign) and isinstance(n.targets[0], ast.Name)}


def functions(tree):
    """(class name or None, function node) of every function and method in the stub."""
    for node in tree.body:
        if isinstance(node, ast.FunctionDef):
            yield None, node
        elif isinstance(node, ast.ClassDef):
            for f in node.body:
                if isinstance(f, ast.FunctionDef):
                    yield node.name, f


def is_property(f):
    return any(isinstance(d, ast.Name) and d.id == "property" for d in f.decorator_list)


def names_in(annotation):
    """The bare names an annotation uses, outside Literal[...] and attribute access."""
    if isinstance(annotation, ast.Name):
        return {annotation.id}
    if isinstance(annotation, ast.Subscript):
        base = names_in(annotation.value)
        if base == {"Literal"}:
            return base
        return base | names_in(annotation.slice)
    if isinstance(annotation, ast.Tuple):
        return set().union(*(names_in(e) for e in annotation.elts))
    if isinstance(annotation, ast.BinOp):
        return names_in(annotation.left) | names_in(annotation.right)
    return set()


def test_every_stub_is_annotated_and_names_what_exists():
    tree = stub_tree()
    imported = {a.asname or a.name for n in tree.body if isinstance(n, ast.ImportFrom)
                for a in n.names}
    assert imported <= TYPING | {"PathLike"}, imported
    known = TYPING | BUILTINS | {"PathLike"} | set(aliases(tree))
    checked = 0
    for owner, f in functions(tree):
        where = f"{owner}.{f.name}" if owner else f.name
        args = f.args
        params = args.posonlyargs + args.args + args.kwonlyargs
        if owner is not None and not any(isinstance(d, ast.Name) and d.id == "staticmethod"
                                         for d in f.decorator_list):
            assert params and params[0].arg == "self" and params[0].annotation is None, where
            params = params[1:]
        for p in params:
            assert p.annotation is not None, (where, p.arg)
        assert args.vararg is None and args.kwarg is None, where
        assert f.returns is not None, (where, "no return annotation")
        for annotation in [p.annotation for p in params] + [f.returns]:
            for name in names_in(annotation):
                assert name in known or isinstance(getattr(mt, name, None), type), (where, name)
        checked += 1
    for name, value in aliases(tree).items():
        for n in names_in(value):
            assert n in known or isinstance(getattr(mt, n, None), type), (name, n)
    assert checked >= 150, checked


class Mismatch(AssertionError):
    pass


def conforms(value, annotation, alias):
    """Whether `value` is of the stub's `annotation`; an annotation this cannot read fails."""
    a = annotation
    if isinstance(a, ast.Constant) and a.value is None:
        return value is None
    if isinstance(a, ast.Name):
        if a.id in alias:
            return conforms(value, alias[a.id], alias)
        if a.id == "Any":
            return True
        if a.id == "int":
            return isinstance(value, int) and not isinstance(value, bool)
        if a.id == "float":
            return isinstance(value, float)
        if a.id in ("str", "bool"):
            return type(value).__name__ == a.id
        cls = getattr(mt, a.id, None)
        if isinstance(cls, type):
            return isinstance(value, cls)
        raise Mismatch(f"unreadable annotation {ast.unparse(a)}")
    if isinstance(a, ast.Subscript):
        base = ast.unparse(a.value)
        args = a.slice.elts if isinstance(a.slice, ast.Tuple) else [a.slice]
        if base == "Optional":
            return value is None or conforms(value, args[0], alias)
        if base == "Union":
            return any(conforms(value, x, alias) for x in args)
        if base == "Literal":
            return any(value == x.value for x in args)
        if base == "list":
            return isinstance(value, list) and all(conforms(v, args[0], alias) for v in value)
        if base == "tuple":
            return (isinstance(value, tuple) and len(value) == len(args)
                    and all(conforms(v, x, alias) for v, x in zip(value, args)))
        if base == "dict":
            return isinstance(value, dict) and all(
                conforms(k, args[0], alias) and conforms(v, args[1], alias)
                for k, v in value.items())
        if base == "Iterator":
            return hasattr(value, "__next__") and all(conforms(v, args[0], alias) for v in value)
        if base == "npt.NDArray":
            if not isinstance(value, np.ndarray):
                return False
            dtype = ast.unparse(args[0])
            return dtype == "Any" or value.dtype == np.dtype(dtype.removeprefix("np."))
    raise Mismatch(f"unreadable annotation {ast.unparse(a)}")


@pytest.fixture(scope="module")
def samples(tmp_path_factory):
    """Objects of every stubbed class, and the calls that made them: (class name, method name,
    the value returned)."""
    calls = []

    def call(owner, name, fn, *args, **kwargs):
        value = fn(*args, **kwargs)
        calls.append((owner, name, value))
        return value

    hand = call("Hand", "preset", mt.Hand.preset, "two-finger")
    call("Hand", "load", mt.Hand.load, "two-finger")
    config = tmp_path_factory.mktemp("hand") / "hand.toml"
    config.write_text('preset = "two-finger"\n')
    call("Hand", "from_file", mt.Hand.from_file, config)
    call("Hand", "rest_vertices", hand.rest_vertices, 0)
    call("Hand", "faces", hand.faces, 0)
    call("Hand", "marker_vertices", hand.marker_vertices, 0)
    call("Hand", "hand_from_finger", hand.hand_from_finger, 0)
    keypoints = call("Hand", "rest_keypoints", hand.rest_keypoints)
    rest = hand.rest_vertices(0)
    base = np.flatnonzero(rest[:, 2] < rest[:, 2].min() + 0.002)
    top = np.argsort(rest[:, 2])[-2:]
    solver = mt.ArapSolver(rest, hand.faces(0), base, top)
    call("ArapSolver", "solve", solver.solve, rest[base], rest[top])
    shape = call("MultiShapeEstimator", "estimate", mt.MultiShapeEstimator(hand).estimate,
                 keypoints)
    model = mt.ContactModel(MODEL, hand)
    call("ContactModel", "estimate", model.estimate, shape)
    call("ModelCard", "to_dict", model.card.to_dict)
    physics = mt.PhysicsEstimator(hand, config=OCCLUDING)
    call("PhysicsEstimator", "estimate", physics.estimate, keypoints, np.zeros((2, 4)))
    call("PhysicsEstimator", "reset", physics.reset)
    episode = call(None, "read_episode", mt.read_episode, EPISODE)
    call(None, "read_ros2_bag", mt.read_ros2_bag, ROS2_EPISODE)
    call(None, "is_ros2_recording", mt.is_ros2_recording, EPISODE)
    call("Episode", "__len__", episode.__len__)
    call("Episode", "__getitem__", episode.__getitem__, -1)
    call("Episode", "__iter__", episode.__iter__)
    pipeline = call("Pipeline", "physics", mt.Pipeline.physics, hand, episode.camera,
                    config=OCCLUDING)
    for f in episode:
        r = call("Pipeline", "process", pipeline.process, f.color, f.depth, f.world_from_hand,
                 f.pulls, time=f.time)
        if r.loads:
            break
    assert r.loads, "a frame of the demo has a load"
    call("Pipeline", "reset", pipeline.reset)
    paper = call("Pipeline", "paper", mt.Pipeline.paper, hand, episode.camera, MODEL)
    f = episode[3]
    call("Pipeline", "process", paper.process, f.color, f.depth, f.world_from_hand, f.pulls)
    dataset = mt.Dataset(DATASET)
    call("Dataset", "__len__", dataset.__len__)
    call("Dataset", "shard", dataset.shard, 0)
    frames = call("Dataset", "frames", dataset.frames)
    call("DatasetFrames", "__iter__", frames.__iter__)
    call("DatasetFrames", "__next__", frames.__next__)
    call("DatasetCard", "to_dict", dataset.card.to_dict)
    objects = [hand, episode.camera, solver, model, physics, pipeline, paper, episode, dataset,
               frames] + [v for _, _, v in calls]
    return calls, objects


def test_the_stubs_say_what_the_module_returns(samples):
    """Every method and function the stub names was called above and returned its stub's type;
    every property of every object reached (following properties into the objects they return)
    is of its stub's type, and every stubbed class with properties was reached."""
    calls, objects = samples
    tree = stub_tree()
    alias = aliases(tree)
    stubs = {(owner, f.name): f for owner, f in functions(tree)}
    properties = {}
    for (owner, name), f in stubs.items():
        if is_property(f):
            properties.setdefault(owner, []).append(f)
    called = set()
    for owner, name, value in calls:
        f = stubs[(owner, name)]
        if name == "__iter__" and owner == "Episode":
            value = iter(list(value))
        assert conforms(value, f.returns, alias), (owner, name, ast.unparse(f.returns), value)
        called.add((owner, name))
    # Constructors return their class; special methods of iteration are checked above.
    methods = {k for k, f in stubs.items() if not is_property(f) and k[1] != "__init__"}
    assert methods - called == set(), sorted(methods - called, key=str)

    reached, seen, queue = set(), set(), list(objects)
    while queue:
        obj = queue.pop()
        if id(obj) in seen or type(obj).__module__ != "moe_touch":
            if isinstance(obj, (list, tuple)):
                queue.extend(obj)
            elif isinstance(obj, dict):
                queue.extend(obj.values())
            continue
        seen.add(id(obj))
        owner = type(obj).__name__
        for f in properties.get(owner, []):
            value = getattr(obj, f.name)
            assert conforms(value, f.returns, alias), (owner, f.name, ast.unparse(f.returns),
                                                      type(value), value)
            queue.append(value)
        reached.add(owner)
    assert set(properties) - reached == set(), set(properties) - reached


def test_the_checker_catches_a_wrong_annotation():
    """The checker above is not one that passes anything."""
    alias = aliases(stub_tree())
    parse = lambda text: ast.parse(text, mode="eval").body  # noqa: E731
    assert not conforms([1.0], parse("list[int]"), alias)
    assert not conforms(np.zeros(3, np.float32), parse("_F64"), alias)
    assert not conforms({"a": 1}, parse("ModelCard"), alias)
    assert not conforms(None, parse("list[ContactLoad]"), alias)
    assert not conforms("dgcnn", parse('Literal["physics"]'), alias)
    assert conforms(None, parse("Optional[_F64]"), alias)
    assert conforms([np.zeros(3)], parse("list[_F64]"), alias)
    with pytest.raises(Mismatch):
        conforms(1, parse("Sequence[int]"), alias)
