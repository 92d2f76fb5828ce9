"""The package's shape: its import graph has no circle (every import, at module level or
inside a function, points one way; design.md section 7), and no function is longer than
MAX_FUNCTION_LINES without a stated reason."""

import ast
import re
import os

SRC = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "src")


def modules():
    out = {}
    for folder, _, files in os.walk(os.path.join(SRC, "dopplertof")):
        for name in files:
            if name.endswith(".py"):
                path = os.path.join(folder, name)
                module = os.path.relpath(path, SRC)[:-3].replace(os.sep, ".")
                out[module.removesuffix(".__init__")] = path
    return out


def imports(module: str, path: str, known) -> set:
    """The package modules ``module`` imports (``from .. import x`` counts as x when x
    is a module, not as the package whose attribute it would be)."""
    package = module if path.endswith("__init__.py") else module.rsplit(".", 1)[0]
    found = set()
    for node in _import_statements(ast.parse(open(path).read())):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                base = ".".join(parts + ([node.module] if node.module else []))
            subs = [f"{base}.{a.name}" for a in node.names]
            targets = [t for t in subs if t in known]
            if len(targets) < len(subs):
                targets.append(base)
        for t in targets:
            while t not in known and "." in t:
                t = t.rsplit(".", 1)[0]
            if t in known and t != module:
                found.add(t)
    return found


def _import_statements(tree):
    """The import statements of ``tree``, at module level or inside functions, with
    each ``lazy_exports(__name__, {".module": names, ...})`` table (dopplertof/lazy.py)
    as the ``from .module import names`` statements it stands for."""
    for node in ast.walk(tree):
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            yield node
        elif (isinstance(node, ast.Call) and getattr(node.func, "id", None) == "lazy_exports"
              and len(node.args) == 2 and isinstance(node.args[1], ast.Dict)):
            for key, names in zip(node.args[1].keys, node.args[1].values):
                module = key.value.lstrip(".")
                yield ast.ImportFrom(module=module or None, level=len(key.value) - len(module),
                                     names=[ast.alias(name=n.value) for n in names.elts])


def test_no_import_circle():
    known = modules()
    graph = {m: imports(m, p, known) for m, p in known.items()}
    state, circles = {}, []

    def visit(m, trail):
        state[m] = "open"
        for n in sorted(graph[m]):
            if state.get(n) == "open":
                circles.append(trail[trail.index(n):] + [n])
            elif n not in state:
                visit(n, trail + [n])
        state[m] = "done"

    for m in sorted(graph):
        if m not in state:
            visit(m, [m])
    assert not circles, "import circles: " + "; ".join(" -> ".join(c) for c in circles)


#: the most lines a function in src/ has (its docstring included; a class it defines,
#: such as the integrator made per variant, is measured method by method)
MAX_FUNCTION_LINES = 60
#: functions allowed to be longer, and why
LONG_FUNCTIONS = {}


def _classes_outside_functions(node):
    """The class definitions in ``node``'s body that no nested function holds."""
    for child in ast.iter_child_nodes(node):
        if isinstance(child, ast.ClassDef):
            yield child
        elif not isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            yield from _classes_outside_functions(child)


def function_lengths():
    """(qualified name, lines) of every function and method in the package."""
    for module, path in modules().items():
        def visit(node, prefix):
            for child in ast.iter_child_nodes(node):
                if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                    lines = child.end_lineno - child.lineno + 1 - sum(
                        c.end_lineno - c.lineno + 1 for c in _classes_outside_functions(child))
                    yield f"{prefix}.{child.name}", lines
                    yield from visit(child, f"{prefix}.{child.name}")
                elif isinstance(child, ast.ClassDef):
                    yield from visit(child, f"{prefix}.{child.name}")
                else:
                    yield from visit(child, prefix)

        yield from visit(ast.parse(open(path).read()), module)


def test_no_function_is_long_without_a_reason():
    lengths = dict(function_lengths())
    long = {name: n for name, n in lengths.items()
            if n > MAX_FUNCTION_LINES and name not in LONG_FUNCTIONS}
    assert not long, f"functions over {MAX_FUNCTION_LINES} lines: {long}"
    stale = [name for name in LONG_FUNCTIONS if lengths.get(name, 0) <= MAX_FUNCTION_LINES]
    assert not stale, f"LONG_FUNCTIONS names functions that are short now or gone: {stale}"


#: rooms on top of the camera layer (tof/): each imports down, and nothing but the command
#: line imports it (the module prefix -> the modules outside it allowed to import it)
TOP_ROOMS = {"dopplertof.cameras": {"dopplertof.cli", "dopplertof.dataset",
                                     # a camera's stream: its frames as cluster tasks
                                     "dopplertof.experiments.stream"},
             "dopplertof.dataset": {"dopplertof.cli"},
             "dopplertof.fmcw": {"dopplertof.cli"}}
#: what a room may not import: its sibling rooms
ROOM_SIBLINGS = {"dopplertof.cameras": ("dopplertof.experiments", "dopplertof.diff",
                                        "dopplertof.cli"),
                 # dataset imports down (cameras, experiments, tof, scene...), never the
                 # command line or the fit
                 "dopplertof.dataset": ("dopplertof.diff", "dopplertof.cli"),
                 # the FMCW lidar (issue 43) imports down (tof, integrators, scene), never
                 # the other rooms or the command line
                 "dopplertof.fmcw": ("dopplertof.cameras", "dopplertof.dataset",
                                     "dopplertof.experiments", "dopplertof.diff",
                                     "dopplertof.cli")}


def _inside(module: str, prefix: str) -> bool:
    return module == prefix or module.startswith(prefix + ".")


def test_top_rooms_import_down_and_only_the_command_line_imports_them():
    known = modules()
    graph = {m: imports(m, p, known) for m, p in known.items()}
    for room in TOP_ROOMS:
        assert any(_inside(m, room) for m in known), f"the room {room} is gone"
    wrong = []
    for room, allowed in TOP_ROOMS.items():
        for module, targets in graph.items():
            if _inside(module, room):
                wrong += [f"{module} -> {t}" for t in targets
                          if any(_inside(t, s) for s in ROOM_SIBLINGS[room])
                          and not _inside(t, room)]
            elif not any(_inside(module, a) for a in allowed):
                wrong += [f"{module} -> {t}" for t in targets if _inside(t, room)]
    assert not wrong, "imports against the layers: " + "; ".join(sorted(wrong))


#: an issue number or a date in src/ (history lives in git); another project's issue
#: tracker (Mitsuba's, the Azure Kinect SDK's) is a reference a reader can follow
_HISTORY = re.compile(r"(?<!Mitsuba )(?<!SDK )(?<!SDK's )\b[Ii]ssues? \d+|\b20\d\d-[01]\d-[0-3]\d\b")


def test_no_issue_numbers_or_dates_in_src_and_no_issue_numbers_in_docs():
    root = os.path.dirname(SRC)
    found = []
    for folder, _, files in os.walk(os.path.join(SRC, "dopplertof")):
        for name in files:
            if name.endswith((".py", ".toml", ".xml")):
                path = os.path.join(folder, name)
                for number, line in enumerate(open(path, encoding="utf-8"), 1):
                    if _HISTORY.search(line):
                        found.append(f"{os.path.relpath(path, root)}:{number}")
    issue = re.compile(_HISTORY.pattern.split("|")[0])
    docs = [os.path.join(root, "README.md")] + [
        os.path.join(root, "docs", n) for n in os.listdir(os.path.join(root, "docs"))
        if n.endswith(".md")]
    for path in docs:
        for number, line in enumerate(open(path, encoding="utf-8"), 1):
            if issue.search(line):
                found.append(f"{os.path.relpath(path, root)}:{number}")
    assert not found, "history outside git: " + ", ".join(found)


#: names that hold dataclasses (a render's setup, its parameters): read inside a Dr.Jit
#: loop they become loop state, and Dr.Jit's traversal of them replaced the FMCW
#: settings' field types in place (tests/test_gradient.py, test_control_variate.py)
_NOT_IN_LOOPS = ("setup", "params")


def test_no_dr_syntax_loop_reads_a_dataclass_by_name():
    """The path loops (functions decorated ``dr.syntax``) read the render's setup and
    parameters only through plain objects (path_steps.LoopSettings, a modality)."""
    found = []
    for module, path in modules().items():
        for node in ast.walk(ast.parse(open(path).read())):
            if isinstance(node, ast.FunctionDef) and any(
                    ast.unparse(d) == "dr.syntax" for d in node.decorator_list):
                for loop in (n for n in ast.walk(node) if isinstance(n, ast.While)):
                    names = {n.id for part in [loop.test, *loop.body]
                             for n in ast.walk(part) if isinstance(n, ast.Name)}
                    found += [f"{module}.{node.name}: {name}"
                              for name in sorted(names & set(_NOT_IN_LOOPS))]
    assert not found, "a dr.syntax loop reads: " + ", ".join(found)
