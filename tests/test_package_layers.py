"""The package's layers, read from its source with `ast`: only canopenfd/_binding/
touches the compiled core, and no module reads another object's `_private`
attributes.

Every .py file of the installed package is parsed; imports count wherever they
are (module level, inside functions, under `if TYPE_CHECKING:`), relative ones
resolved against the importing module, a package's __init__ being the module
named like the package.
"""

from __future__ import annotations

import ast
import pathlib
from typing import Dict, Iterator, List, NamedTuple, Tuple

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
PRIVATE_ACCESS_ALLOWED = {
    **{("cli_usdo.py", expression): "cli_usdo.py calls cli.py's module-private helpers; "
       "both files are being rebuilt as canopenfd/cli/ in another branch, which owns the fix"
       for expression in ("_cli._network", "_cli._open_line", "_cli._shutdown",
                          "_cli._owned")},
}


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
