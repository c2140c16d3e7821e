"""The shape of the package: no import cycle, one home for exceptions, deprecated names.

The import graph is read from the source with :mod:`ast`, not from
``sys.modules``: every ``import`` statement counts, at module level and inside
functions alike (a function-level import is a cycle postponed, not removed).
Imports under ``if TYPE_CHECKING:`` are skipped, as they never run.
"""

import ast
import importlib
import inspect
import pkgutil
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

import gpmultirate
import gpmultirate.exceptions

PACKAGE = Path(gpmultirate.__file__).parent
ROOT = "gpmultirate"


# ------------------------------------------------------------- import graph
def package_modules() -> dict[str, tuple[str, bool]]:
    """Every module of the package: dotted name -> (source, is a package)."""
    modules = {}
    for path in PACKAGE.rglob("*.py"):
        parts = [ROOT, *path.relative_to(PACKAGE).with_suffix("").parts]
        is_package = parts[-1] == "__init__"
        if is_package:
            parts.pop()
        modules[".".join(parts)] = (path.read_text(encoding="utf-8"), is_package)
    return modules


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


class _Imports(ast.NodeVisitor):
    """The dotted names a module imports, each with whether it is inside a function."""

    def __init__(self, package: str):
        self.package = package
        self.depth = 0
        self.found: list[tuple[str | tuple[str, str], bool]] = []

    def visit_FunctionDef(self, node):
        self.depth += 1
        self.generic_visit(node)
        self.depth -= 1

    visit_AsyncFunctionDef = visit_FunctionDef

    def visit_If(self, node):
        if _is_type_checking(node.test):
            for child in node.orelse:
                self.visit(child)
            return
        self.generic_visit(node)

    def visit_Import(self, node):
        self.found += [(alias.name, self.depth > 0) for alias in node.names]

    def visit_ImportFrom(self, node):
        base = node.module or ""
        if node.level:
            parts = self.package.split(".")
            parts = parts[: len(parts) - node.level + 1]
            base = ".".join(parts + ([node.module] if node.module else []))
        # "from a import b" imports the module a.b when there is one, else reads b from a
        self.found += [((base, alias.name), self.depth > 0) for alias in node.names]


def import_graph(modules: dict, function_level: bool = True) -> dict[str, set[str]]:
    """Edges ``importer -> imported`` among the package's modules.

    Importing ``a.b.c`` runs the ``__init__`` of ``a.b`` too: that edge is
    counted, except for the packages that contain the importer (whose
    ``__init__`` is already running) and the top-level package, whose
    ``__init__`` is the public facade that imports everything.
    """
    def known(name: str) -> str | None:
        parts = name.split(".")
        while parts:
            if ".".join(parts) in modules:
                return ".".join(parts)
            parts.pop()
        return None

    graph = {}
    for name, (source, is_package) in modules.items():
        visitor = _Imports(name if is_package else name.rpartition(".")[0])
        visitor.visit(ast.parse(source))
        edges = set()
        for imported, in_function in visitor.found:
            if isinstance(imported, tuple):
                base, attribute = imported
                submodule = f"{base}.{attribute}"
                imported = submodule if submodule in modules else base
            if (in_function and not function_level) or not imported.startswith(ROOT):
                continue
            target = known(imported)
            if target is None:
                continue
            parts = target.split(".")
            for k in range(2, len(parts) + 1):
                ancestor = ".".join(parts[:k])
                if ancestor == target or not (name == ancestor or name.startswith(ancestor + ".")):
                    edges.add(ancestor)
        edges.discard(name)
        edges.discard(ROOT)
        graph[name] = edges
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan)."""
    index, low, on_stack, stack, found = {}, {}, set(), [], []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_the_checker_finds_planted_cycles():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": set()}) == []
    planted = {
        "gpmultirate": ("from gpmultirate import low", True),
        "gpmultirate.low": ("def f():\n    from gpmultirate.sub.leaf import x\n", False),
        "gpmultirate.sub": ("from gpmultirate.sub.middle import y", True),
        "gpmultirate.sub.middle": ("from . import leaf\nimport numpy", False),
        "gpmultirate.sub.leaf": ("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
                                 "    import gpmultirate.low\n", False),
        "gpmultirate.sub.other": ("from gpmultirate.low import f", False),
    }
    graph = import_graph(planted)
    # importing sub.leaf runs sub/__init__ (not the facade, nor one's own package)
    assert graph["gpmultirate.low"] == {"gpmultirate.sub", "gpmultirate.sub.leaf"}
    assert graph["gpmultirate.sub.middle"] == {"gpmultirate.sub.leaf"}
    assert graph["gpmultirate.sub.leaf"] == set()  # TYPE_CHECKING never runs
    assert cycles(graph) == []
    assert import_graph(planted, function_level=False)["gpmultirate.low"] == set()
    # low -> sub -> middle -> leaf, and a run-time edge back from leaf to low
    planted["gpmultirate.sub.leaf"] = ("def g():\n    import gpmultirate.low\n", False)
    graph = import_graph(planted)
    assert cycles(graph) == [["gpmultirate.low", "gpmultirate.sub", "gpmultirate.sub.leaf",
                              "gpmultirate.sub.middle"]]
    assert cycles(import_graph(planted, function_level=False)) == []


def test_no_import_cycle_among_the_package_modules():
    """Module-level and function-level imports together: the strict rule is enforced."""
    modules = package_modules()
    graph = import_graph(modules, function_level=True)
    assert len(graph) == len(modules) > 40
    assert cycles(graph) == []


def test_every_module_imports():
    for info in pkgutil.walk_packages([str(PACKAGE)], prefix=f"{ROOT}."):
        if info.name.endswith("__main__"):
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("error", DeprecationWarning)
            importlib.import_module(info.name)


# ------------------------------------------------------------ exceptions
def test_every_exception_and_warning_class_is_defined_in_the_exceptions_module():
    defined_elsewhere = []
    n_found = 0
    for name in package_modules():
        if name.endswith("__main__"):
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("error", DeprecationWarning)
            module = importlib.import_module(name)
        for _, cls in inspect.getmembers(module, inspect.isclass):
            if not cls.__module__.startswith(ROOT):
                continue
            if issubclass(cls, (BaseException, Warning)):
                n_found += 1
                if cls.__module__ != "gpmultirate.exceptions":
                    defined_elsewhere.append(f"{cls.__module__}.{cls.__qualname__}")
    assert defined_elsewhere == []
    assert n_found >= 7


_EXCEPTION_BASES = ("Error", "Exception", "Warning", "Interrupt", "Exit")


def test_no_exception_class_is_defined_elsewhere_even_inside_a_function():
    """The source too: a class with an exception base, at any depth, outside exceptions.py."""
    found = []
    for name, (source, _) in package_modules().items():
        if name == "gpmultirate.exceptions":
            continue
        for node in ast.walk(ast.parse(source)):
            if not isinstance(node, ast.ClassDef):
                continue
            bases = [b.id if isinstance(b, ast.Name) else getattr(b, "attr", "")
                     for b in node.bases]
            if any(base.endswith(_EXCEPTION_BASES) for base in bases):
                found.append(f"{name}.{node.name}")
    assert found == []
    tree = ast.parse(package_modules()["gpmultirate.exceptions"][0])
    assert sum(isinstance(node, ast.ClassDef) for node in ast.walk(tree)) == len(
        gpmultirate.exceptions.__all__)


def test_exceptions_keep_their_former_homes():
    from gpmultirate import exceptions, io, memory, persistence
    from gpmultirate.study import journal

    assert io.DataFileError is exceptions.DataFileError
    assert persistence.ModelFileError is exceptions.ModelFileError is gpmultirate.ModelFileError
    assert memory.MemoryLimitError is exceptions.MemoryLimitError
    assert journal.JournalError is exceptions.JournalError
    assert gpmultirate.IdentifiabilityError is exceptions.IdentifiabilityError
    assert gpmultirate.NumericalWarning is exceptions.NumericalWarning
    assert gpmultirate.HeldOutWarning is exceptions.HeldOutWarning
    assert gpmultirate.io.DataFileError is exceptions.DataFileError
    for name in exceptions.__all__:
        assert getattr(exceptions, name).__module__ == "gpmultirate.exceptions"


def test_the_memory_refusal_is_a_value_error_and_a_memory_error(monkeypatch):
    from gpmultirate.exceptions import MemoryLimitError
    from gpmultirate.memory import LIMIT_VARIABLE, check_fit_memory

    monkeypatch.setenv(LIMIT_VARIABLE, "1000")
    with pytest.raises(MemoryLimitError) as info:
        check_fit_memory(10, 1000, 2)
    assert isinstance(info.value, ValueError) and isinstance(info.value, MemoryError)
    # so that "except ValueError" (the command line's one-line errors) catches it
    try:
        check_fit_memory(10, 1000, 2)
    except ValueError as error:
        assert "GB" in str(error)
    else:  # pragma: no cover
        pytest.fail("no refusal")


# ------------------------------------------------------------ deprecations
# names deprecated in 0.1.0 and removed in 0.2.0, with their new homes
REMOVED_MODULES = {
    "gpmultirate.operator": "gpmultirate.observations",
    "gpmultirate.frequency": "gpmultirate.responses",
    "gpmultirate.experiments": "gpmultirate.study",
}
REPOSITORY = PACKAGE.parent


def test_the_names_deprecated_in_0_1_are_removed_in_0_2():
    import gpmultirate.plotting as plotting
    from gpmultirate.deprecation import REMOVED_IN

    assert gpmultirate.__version__.startswith("0.2.") and REMOVED_IN == "0.3.0"
    for old in REMOVED_MODULES:
        sys.modules.pop(old, None)
        with pytest.raises(ModuleNotFoundError):
            importlib.import_module(old)
    for name in ("nonidentifiable_example", "NonidentifiableExample"):
        with pytest.raises(AttributeError, match=name):
            getattr(plotting, name)
    with pytest.raises(ModuleNotFoundError):
        importlib.import_module("gpmultirate.kernels.offsets")
    with pytest.raises(TypeError, match="operator"):
        gpmultirate.ObservedKernel(gpmultirate.kernels.DC(), operator=None)
    assert not hasattr(gpmultirate.ObservedKernel, "operator")
    assert not hasattr(gpmultirate.FIRGaussianProcess, "operator_")


def test_the_changelog_names_each_removed_name_with_its_new_home():
    changelog = (REPOSITORY / "CHANGELOG.md").read_text(encoding="utf-8")
    removed = changelog[changelog.index("### Removed"):]
    for old, new in REMOVED_MODULES.items():
        assert f"`{old}`" in removed and f"`{new}`" in removed


def test_the_deprecation_of_a_name_names_its_new_home_and_the_next_minor_version():
    from gpmultirate.deprecation import warn_deprecated

    with pytest.warns(DeprecationWarning, match=r"gpmultirate.old .*0\.2.*0\.3\.0: use gpmultirate.new"):
        warn_deprecated("gpmultirate.old", "gpmultirate.new")


# the removed names may appear only where their removal is stated
_OLD_NAMES = ("gpmultirate.operator", "gpmultirate.frequency", "gpmultirate.experiments",
              ".operator_", "import experiments", "plotting import nonidentifiable_example",
              "plotting import NonidentifiableExample")
_ALLOWED = {"tests/test_package_structure.py", "CHANGELOG.md", "docs/api.rst"}


def test_tests_docs_and_examples_use_the_new_homes():
    files = [*REPOSITORY.glob("tests/*.py"), *REPOSITORY.glob("examples/*.py"),
             *REPOSITORY.glob("benchmarks/*.py"), *REPOSITORY.glob("docs/*.rst"),
             *REPOSITORY.glob("*.md"), *PACKAGE.rglob("*.py")]
    assert len(files) > 60
    found = []
    for path in files:
        relative = path.relative_to(REPOSITORY).as_posix()
        if relative in _ALLOWED:
            continue
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            found += [f"{relative}:{number}: {old}" for old in _OLD_NAMES if old in line]
    assert found == []


def test_command_line_module_stays_thin():
    # the command parses arguments and calls library functions (io, report, export,
    # arguments, progress): its module stays short enough to read in one sitting
    source = Path(gpmultirate.__file__).parent / "cli.py"
    assert len(source.read_text().splitlines()) <= 600
