"""The package's layers, read from its source with `ast`: no import cycles
(not even for types), only canopenfd/_binding/ touches the compiled core, and
no module reads another object's `_private` attributes.

Every .py file of the installed package is parsed; imports count wherever they
are (module level, inside functions, under `if TYPE_CHECKING:`), relative ones
resolved against the importing module, a package's __init__ being the module
named like the package.
"""

from __future__ import annotations

import ast
import pathlib
from typing import Dict, Iterator, List, NamedTuple, Set, Tuple

import pytest

import canopenfd

PACKAGE_DIR = pathlib.Path(canopenfd.__file__).resolve().parent
BINDING = "canopenfd._binding"


class Module(NamedTuple):
    name: str          # canopenfd.services.nmt; a package's __init__: canopenfd.services
    path: pathlib.Path
    is_package: bool
    tree: ast.Module


def package_modules() -> Dict[str, Module]:
    modules = {}
    for path in sorted(PACKAGE_DIR.rglob("*.py")):
        parts = list(path.relative_to(PACKAGE_DIR.parent).with_suffix("").parts)
        is_package = parts[-1] == "__init__"
        if is_package:
            parts.pop()
        name = ".".join(parts)
        modules[name] = Module(name, path, is_package,
                               ast.parse(path.read_text(encoding="utf-8"), str(path)))
    return modules


MODULES = package_modules()


class Import(NamedTuple):
    line: int
    module: str        # the module named after `from` / `import`, resolved
    names: Tuple[str, ...]   # what `from module import ...` takes; () for `import module`


def imports(module: Module) -> Iterator[Import]:
    """Every import statement of a module, relative ones resolved."""
    for node in ast.walk(module.tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield Import(node.lineno, alias.name, ())
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = module.name.split(".")
                if not module.is_package:
                    base.pop()
                base = base[:len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            yield Import(node.lineno, target, tuple(alias.name for alias in node.names))


def in_binding(name: str) -> bool:
    return name == BINDING or name.startswith(BINDING + ".")


def import_graph() -> Dict[str, Set[str]]:
    """{module: the package's modules it imports}. `from pkg import name` goes to
    the submodule pkg.name when there is one, else to pkg (its __init__);
    importing a submodule does not count its parent packages (their __init__
    runs first, but it is not what the module uses)."""
    graph: Dict[str, Set[str]] = {}
    for module in MODULES.values():
        targets = set()
        for found in imports(module):
            if not found.names:
                targets.add(found.module)
            for name in found.names:
                submodule = f"{found.module}.{name}"
                targets.add(submodule if submodule in MODULES else found.module)
        graph[module.name] = {target for target in targets
                              if target in MODULES and target != module.name}
    return graph


def cycles(graph: Dict[str, Set[str]]) -> List[List[str]]:
    """One cycle (a -> b -> ... -> a) per strongly connected group of modules."""
    index: Dict[str, int] = {}
    low: Dict[str, int] = {}
    stack: List[str] = []
    on_stack: Set[str] = set()
    groups: List[Set[str]] = []

    def visit(start: str) -> None:      # Tarjan's algorithm, iteratively
        work = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                group = set()
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    group.add(member)
                    if member == node:
                        break
                if len(group) > 1:
                    groups.append(group)

    for name in sorted(graph):
        if name not in index:
            visit(name)
    return [_cycle_in(graph, group) for group in groups]


def _cycle_in(graph: Dict[str, Set[str]], group: Set[str]) -> List[str]:
    """A shortest path from the group's first module back to itself."""
    start = min(group)
    paths = {start: [start]}
    queue = [start]
    while queue:
        node = queue.pop(0)
        for child in sorted(graph[node] & group):
            if child == start:
                return paths[node] + [start]
            if child not in paths:
                paths[child] = paths[node] + [child]
                queue.append(child)
    raise AssertionError(f"no cycle through {start} in {sorted(group)}")


def _named(found: List[List[str]]) -> str:
    return "\n".join(" -> ".join(cycle) for cycle in found)


def test_the_cycle_finder_names_a_cycle():
    graph = {"p.a": {"p.b"}, "p.b": {"p.c"}, "p.c": {"p.a", "p.d"}, "p.d": set()}
    assert cycles(graph) == [["p.a", "p.b", "p.c", "p.a"]]
    assert cycles({"p.a": {"p.b"}, "p.b": set()}) == []


def test_no_import_cycles():
    """Type-only imports count: a cycle is a cycle (types go down a layer or
    into a Protocol instead)."""
    found = cycles(import_graph())
    assert not found, "import cycles:\n" + _named(found)


def test_every_package_is_listed_in_pyproject():
    """`pip install .` installs only the packages pyproject.toml lists."""
    tomllib = pytest.importorskip("tomllib")
    pyproject = PACKAGE_DIR.parent / "pyproject.toml"
    if not pyproject.exists():
        pytest.skip("the package is installed outside its source tree")
    listed = set(tomllib.loads(pyproject.read_text(encoding="utf-8"))
                 ["tool"]["setuptools"]["packages"])
    packages = {module.name for module in MODULES.values() if module.is_package}
    assert packages <= listed, f"not in [tool.setuptools] packages: {sorted(packages - listed)}"


def test_the_package_is_read():
    assert {"canopenfd", "canopenfd.network", "canopenfd.line", BINDING,
            BINDING + ".core"} <= set(MODULES)


def test_only_the_binding_imports_the_compiled_core():
    """canopenfd._core (and its ffi / lib) is imported by canopenfd/_binding/ only;
    everything else gets Python values from the binding's modules."""
    offenders: List[str] = []
    for module in MODULES.values():
        if in_binding(module.name):
            continue
        for found in imports(module):
            takes_core = found.module == "canopenfd._core" or (
                found.module == "canopenfd" and "_core" in found.names)
            takes_cffi = found.module.startswith("canopenfd") and \
                bool({"ffi", "lib"} & set(found.names))
            if takes_core or takes_cffi:
                offenders.append(f"{module.path.relative_to(PACKAGE_DIR.parent)}:{found.line}: "
                                 f"{found.module} {found.names or ''}")
    assert not offenders, "the compiled core imported outside canopenfd/_binding/:\n" + \
        "\n".join(offenders)


# Reads of `_private` attributes of objects other than self / cls, allowed with
# a reason: {(file under canopenfd/, the expression): why}. Keep this tiny.
PRIVATE_ACCESS_ALLOWED: dict = {}


def _is_self(node: ast.expr) -> bool:
    """self, cls, or super() (the object itself, seen from its base class)."""
    if isinstance(node, ast.Name):
        return node.id in ("self", "cls")
    return isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and \
        node.func.id == "super" and not node.args


def test_no_module_reads_another_objects_private_attributes():
    """A service, node or line uses what other objects offer publicly (the line
    context, the services' methods), never their internals."""
    found = []
    for module in MODULES.values():
        where = module.path.relative_to(PACKAGE_DIR).as_posix()
        for node in ast.walk(module.tree):
            if not isinstance(node, ast.Attribute):
                continue
            name = node.attr
            if not name.startswith("_") or (name.startswith("__") and name.endswith("__")):
                continue
            if _is_self(node.value) or (where, ast.unparse(node)) in PRIVATE_ACCESS_ALLOWED:
                continue
            found.append(f"{where}:{node.lineno}: {ast.unparse(node)}")
    assert not found, "private attributes of other objects read:\n" + "\n".join(found)
