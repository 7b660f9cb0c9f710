"""The maintainability figures of the product code (``app/``, ``devices/``, ``pages/``), one per line::

    python -m tools.metrics            # the figures
    python -m tools.metrics --list     # and where each one comes from

Each figure is read from the source with :mod:`ast` (comments and strings do not count):

* ``long_modules``: modules over ``LONG_MODULE_LINES`` lines;
* ``large_classes``: classes with more than ``LARGE_CLASS_ATTRIBUTES`` attributes (names assigned in the
  class body, dataclass fields among them, and ``self.<name>`` assigned in its methods; methods and
  properties are not attributes);
* ``getattr_default``: ``getattr(obj, name, default)`` calls (probing for what an object may have);
* ``hasattr``: ``hasattr(obj, name)`` calls;
* ``except_exception``: ``except Exception`` handlers (alone or in a tuple) and bare ``except:``;
* ``private_access``: a private name (one leading underscore) read or written on anything but ``self``,
  ``cls`` or ``super()``: another object's attribute, a library's, or another module's
  (``getattr``/``setattr``/``hasattr`` with such a name as a literal count too);
* ``exception_roots``: exception classes of the project whose bases are none of the project's exception
  classes (one root: every refusal a caller can catch by one type).

``tests/app/test_metrics.py`` holds the figures that are rules as ceilings.
"""

from __future__ import annotations

import argparse
import ast
import builtins
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PRODUCT = ("app", "devices", "pages")
LONG_MODULE_LINES = 700
LARGE_CLASS_ATTRIBUTES = 30
OWN_NAMES = {"self", "cls"}
BROAD = {"Exception"}  # ``except BaseException: ...; raise`` is a clean-up, not a catch-all
BUILTIN_EXCEPTIONS = {name for name, obj in vars(builtins).items() if isinstance(obj, type) and issubclass(obj, BaseException)}


@dataclass
class Figure:
    """One figure: its count and where each counted thing is (``path:line text``)."""

    name: str
    places: list[str] = field(default_factory=list)

    @property
    def count(self) -> int:
        return len(self.places)


def product_files(root: Path = ROOT) -> Iterator[Path]:
    for package in PRODUCT:
        yield from sorted((root / package).rglob("*.py"))


def _name_of(node: ast.expr) -> str:
    """The last name of ``a.b.C`` or ``C`` (a subscript's base: ``Generic[T]`` -> ``Generic``)."""
    if isinstance(node, ast.Subscript):
        node = node.value
    if isinstance(node, ast.Attribute):
        return node.attr
    if isinstance(node, ast.Name):
        return node.id
    return ""


NAMEDTUPLE_API = {"_make", "_replace", "_asdict", "_fields", "_field_defaults"}  # public, underscored against field names


def _is_private(name: str) -> bool:
    """One leading underscore (or a mangled ``__name``), not a dunder, not namedtuple's public methods."""
    dunder = name.startswith("__") and name.endswith("__")
    gettext = name == "_"  # the translation function by gettext's convention, not a private name
    return name.startswith("_") and not dunder and not gettext and name not in NAMEDTUPLE_API


def _is_own(node: ast.expr) -> bool:
    """``self``, ``cls`` or ``super()``: the object's own attributes."""
    if isinstance(node, ast.Name):
        return node.id in OWN_NAMES
    return isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "super"


def _targets(node: ast.AST) -> Iterator[ast.expr]:
    if isinstance(node, ast.Assign):
        for target in node.targets:
            yield from _flatten(target)
    elif isinstance(node, (ast.AnnAssign, ast.AugAssign)):
        yield from _flatten(node.target)


def _flatten(target: ast.expr) -> Iterator[ast.expr]:
    if isinstance(target, (ast.Tuple, ast.List)):
        for element in target.elts:
            yield from _flatten(element)
    elif isinstance(target, ast.Starred):
        yield from _flatten(target.value)
    else:
        yield target


def class_attributes(cls: ast.ClassDef) -> set[str]:
    """Names assigned in the class body and ``self.<name>`` assigned in its own methods (not nested classes)."""
    names: set[str] = set()
    for statement in cls.body:
        for target in _targets(statement):
            if isinstance(target, ast.Name):
                names.add(target.id)
    stack: list[ast.AST] = [s for s in cls.body if isinstance(s, (ast.FunctionDef, ast.AsyncFunctionDef))]
    while stack:
        node = stack.pop()
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.ClassDef):
                continue
            for target in _targets(child):
                if isinstance(target, ast.Attribute) and isinstance(target.value, ast.Name) and target.value.id == "self":
                    names.add(target.attr)
            stack.append(child)
    return names


class Measure:
    """Walks the product code once and gathers every figure."""

    def __init__(self, root: Path = ROOT):
        self.root = root
        self.long_modules = Figure("long_modules")
        self.large_classes = Figure("large_classes")
        self.getattr_default = Figure("getattr_default")
        self.hasattr = Figure("hasattr")
        self.except_exception = Figure("except_exception")
        self.private_access = Figure("private_access")
        self.exception_roots = Figure("exception_roots")
        self._classes: list[tuple[str, ast.ClassDef]] = []
        for path in product_files(root):
            self._module(path)
        self._roots()

    def figures(self) -> list[Figure]:
        return [self.long_modules, self.large_classes, self.getattr_default, self.hasattr, self.except_exception,
                self.private_access, self.exception_roots]

    def _module(self, path: Path) -> None:
        rel = path.relative_to(self.root).as_posix()
        text = path.read_text(encoding="utf-8")
        lines = text.count("\n") + (0 if text.endswith("\n") or not text else 1)
        if lines > LONG_MODULE_LINES:
            self.long_modules.places.append(f"{rel} {lines} lines")
        tree = ast.parse(text, filename=rel)
        source = text.splitlines()

        def at(node: ast.AST) -> str:
            line = node.lineno
            return f"{rel}:{line} {source[line - 1].strip()[:100]}"

        for node in ast.walk(tree):
            if isinstance(node, ast.ClassDef):
                self._classes.append((rel, node))
                attributes = class_attributes(node)
                if len(attributes) > LARGE_CLASS_ATTRIBUTES:
                    self.large_classes.places.append(f"{rel}:{node.lineno} {node.name} {len(attributes)} attributes")
            elif isinstance(node, ast.Call) and isinstance(node.func, ast.Name):
                func = node.func.id
                if func == "getattr" and len(node.args) >= 3:
                    self.getattr_default.places.append(at(node))
                elif func == "hasattr":
                    self.hasattr.places.append(at(node))
                if (func in ("getattr", "setattr", "hasattr", "delattr") and len(node.args) >= 2
                        and isinstance(node.args[1], ast.Constant) and isinstance(node.args[1].value, str)
                        and _is_private(node.args[1].value) and not _is_own(node.args[0])):
                    self.private_access.places.append(at(node))
            elif isinstance(node, ast.ExceptHandler):
                if node.type is None or any(_name_of(t) in BROAD for t in _flatten(node.type)):
                    self.except_exception.places.append(at(node))
            elif isinstance(node, ast.Attribute) and _is_private(node.attr) and not _is_own(node.value):
                self.private_access.places.append(at(node))
            elif isinstance(node, ast.ImportFrom) and node.module:
                for alias in node.names:  # another module's private name, imported
                    if _is_private(alias.name):
                        self.private_access.places.append(f"{at(node)[:60]} ... {alias.name}")

    def _roots(self) -> None:
        """Exception classes whose bases are none of the project's exception classes."""
        by_name: dict[str, list[ast.ClassDef]] = {}
        for _rel, cls in self._classes:
            by_name.setdefault(cls.name, []).append(cls)
        exceptions: set[str] = set()
        changed = True
        while changed:  # a class is an exception when a base is one: builtin, a library's (...Error) or the project's
            changed = False
            for _rel, cls in self._classes:
                if cls.name in exceptions:
                    continue
                for base in cls.bases:
                    name = _name_of(base)
                    if (name in exceptions or name in BUILTIN_EXCEPTIONS
                            or (name not in by_name and name.endswith(("Error", "Exception")))):
                        exceptions.add(cls.name)
                        changed = True
                        break
        for rel, cls in self._classes:
            if cls.name not in exceptions:
                continue
            project_bases = [b for b in cls.bases if _name_of(b) in exceptions
                             and not (isinstance(b, ast.Name) and b.id == cls.name)]  # errors.CommandError: another module's
            if not project_bases:
                bases = ", ".join(ast.unparse(b) for b in cls.bases)
                self.exception_roots.places.append(f"{rel}:{cls.lineno} {cls.name}({bases})")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--list", action="store_true", help="also list where each counted thing is")
    args = parser.parse_args(argv)
    measure = Measure()
    for figure in measure.figures():
        print(f"{figure.name}: {figure.count}")
        if args.list:
            for place in figure.places:
                print(f"    {place}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
