"""A contribution: the folder of a composite, with its sibling composites, WSDLs and modules.

* Composites are found by QName (``{targetNamespace}name``) among the ``.composite`` files
  of the folder (not subfolders); a sibling that cannot be parsed matters only if
  something refers to a QName it might hold (its problems are then reported).
* WSDL 1.1 ``portType`` s of the ``.wsdl`` files there back ``interface.wsdl``.
* The folder is put on ``sys.path`` so ``implementation.python`` imports modules by
  plain name; a module of the same name imported earlier from another folder is
  replaced by this folder's one.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

from lxml import etree

from scart import errors as E
from scart.api import InterfaceInfo, Operation
from scart.errors import Problem
from scart.model import Composite, Location
from scart.scdl import Loader, parse_xml

WSDL_NS = "http://schemas.xmlsoap.org/wsdl/"


class Contribution:
    """The folder of a root composite. Not thread-safe (loading is single-threaded)."""

    def __init__(self, root_file: str, is_element: Callable[[str], bool] = lambda name: False) -> None:
        self.root_file = root_file
        self.folder = Path(root_file).resolve().parent
        self.is_element = is_element  # which <scart:NAME> composite children are extension elements
        self.problems: list[Problem] = []
        self._by_qname: dict[str, str] | None = None
        self._same_qname: dict[str, list[str]] = {}  # QName -> every file declaring it (when more than one)
        self._loaded: dict[str, Composite | None] = {}  # QName -> loaded once, reused (problems reported once)
        self._sibling_problems: list[Problem] = []
        self._loading: list[str] = []
        self._wsdl: dict[str, InterfaceInfo] | None = None

    def load_root(self) -> Composite | None:
        """Load the root composite (and whatever it refers to); problems in ``self.problems``."""
        return self._load(self.root_file)

    def _load(self, path: str) -> Composite | None:
        loader = Loader(path, self.resolve, self.is_element)
        self._loading.append(str(Path(path).resolve()))
        try:
            comp = loader.load()
        finally:
            self._loading.pop()
        self.problems.extend(loader.problems)
        return comp

    def resolve(self, qname: str, where: Location) -> Composite | None:
        """The composite called ``qname`` in this folder, loaded on first use; None if unknown
        or if using it would make a cycle (reported at ``where``)."""
        index = self._index()
        path = index.get(qname)
        if path is None:
            self.problems.extend(self._sibling_problems)
            self._sibling_problems = []
            return None
        if str(Path(path).resolve()) in self._loading:
            self.problems.append(Problem(E.SCART_COMPOSITE_CYCLE, f"composite {qname} refers back to itself "
                                         f"(cycle through {Path(path).name})", where.path, where.line))
            return None
        files = self._same_qname.pop(qname, None)
        if files:
            self.problems.append(Problem(E.SCART_DUPLICATE_COMPOSITE, f"composite {qname} is declared by several "
                                         f"files: {', '.join(files)}; using {files[0]}", where.path, where.line))
        if qname not in self._loaded:
            self._loaded[qname] = self._load(path)
        return self._loaded[qname]

    def _parse_all(self, pattern: str) -> Iterator[tuple[Path, etree._Element | None, list[Problem]]]:
        """Each file of the folder matching ``pattern`` (sorted), parsed: ``(file, root or
        None, its parse problems)``; the caller decides where the problems go."""
        for file in sorted(self.folder.glob(pattern)):
            problems: list[Problem] = []
            root = parse_xml(str(file), problems)
            yield file, root, problems

    def _index(self) -> dict[str, str]:
        if self._by_qname is None:
            self._by_qname = {}
            for file, root, problems in self._parse_all("*.composite"):
                if root is None:
                    self._sibling_problems.extend(problems)
                    continue
                qname = f"{{{root.get('targetNamespace', '')}}}{root.get('name', '')}"
                shown = str(Path(self.root_file).parent / file.name)  # as the root's path is shown
                if qname in self._by_qname:
                    self._same_qname.setdefault(qname, [self._by_qname[qname]]).append(shown)
                    continue
                self._by_qname[qname] = shown
        return self._by_qname

    def import_object(self, ref: str) -> object:
        """Import ``"pkg.mod:Attr"`` from this contribution (see :func:`import_object`)."""
        return import_object(ref, self.folder)

    # --- WSDL ---------------------------------------------------------------------------

    def wsdl_interface(self, target: str, where: Location) -> InterfaceInfo | None:
        """The portType named by ``ns#wsdl.interface(Name)``; None (problem recorded) if absent."""
        ns, _, rest = target.partition("#")
        name = rest[len("wsdl.interface("):-1] if rest.startswith("wsdl.interface(") and rest.endswith(")") else rest
        found = self._wsdl_index().get(f"{{{ns}}}{name}")
        if found is None:
            self.problems.append(Problem(E.SCART_WSDL, f"no WSDL portType {name!r} in namespace {ns!r} "
                                         "in the contribution", where.path, where.line))
        return found

    def _wsdl_index(self) -> dict[str, InterfaceInfo]:
        if self._wsdl is None:
            self._wsdl = {}
            for _, root, problems in self._parse_all("*.wsdl"):
                self.problems.extend(problems)
                if root is not None:
                    self._wsdl.update(read_port_types(root))
        return self._wsdl


def read_port_types(root: etree._Element) -> dict[str, InterfaceInfo]:
    """WSDL 1.1 ``portType`` s of a parsed ``definitions`` element, by Clark QName.

    An operation with an ``input`` and no ``output`` is one-way.
    """
    tns = root.get("targetNamespace", "")
    out: dict[str, InterfaceInfo] = {}
    for pt in root.iterchildren(f"{{{WSDL_NS}}}portType"):
        ops: dict[str, Operation] = {}
        for op in pt.iterchildren(f"{{{WSDL_NS}}}operation"):
            has_out = op.find(f"{{{WSDL_NS}}}output") is not None
            ops[op.get("name", "")] = Operation(op.get("name", ""), oneway=not has_out, returns_value=has_out)
        out[f"{{{tns}}}{pt.get('name', '')}"] = InterfaceInfo(pt.get("name", ""), ops, remotable=True)
    return out


def import_object(ref: str, folder: Path) -> object:
    """Import ``"pkg.mod:Attr"`` with ``folder`` first on ``sys.path``.

    Raises ``ImportError``/``AttributeError``/``ValueError`` (callers turn them into problems).
    """
    module_name, sep, attr = ref.partition(":")
    if not sep or not module_name or not attr:
        raise ValueError(f"{ref!r} is not of the form 'package.module:Class'")
    folder_s = str(folder)
    if not sys.path or sys.path[0] != folder_s:
        if folder_s in sys.path:
            sys.path.remove(folder_s)
        sys.path.insert(0, folder_s)
    _forget_foreign(module_name.split(".")[0], folder)
    obj: object = importlib.import_module(module_name)
    for part in attr.split("."):
        obj = getattr(obj, part)
    return obj


def _forget_foreign(top: str, folder: Path) -> None:
    """Drop ``top`` (and submodules) from ``sys.modules`` if this folder has its own copy."""
    mine = folder / f"{top}.py"
    pkg = folder / top / "__init__.py"
    if not (mine.exists() or pkg.exists()):
        return
    existing = sys.modules.get(top)
    if existing is None:
        return
    origin = getattr(existing, "__file__", None)
    if origin and Path(origin).resolve() in (mine.resolve(), pkg.resolve()):
        return
    for name in [m for m in sys.modules if m == top or m.startswith(top + ".")]:
        del sys.modules[name]
    importlib.invalidate_caches()
