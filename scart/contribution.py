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

import dataclasses
import importlib
import re
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

from lxml import etree

from scart import errors as E
from scart.api import InterfaceInfo, Operation
from scart.errors import Problem
from scart.model import SCA10_NS, SCA11_NS, Composite, Location
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

    def wsdl_interface(self, target: str, where: Location, attribute: str = "interface") -> InterfaceInfo | None:
        """The portType named by ``ns#wsdl.porttype(Name)`` (SCA 1.1, WSDL 1.1) or
        ``ns#wsdl.interface(Name)`` (SCA 1.0, WSDL 2.0); None (problem recorded) if the form
        is wrong or no ``.wsdl`` file of the contribution declares it."""
        code = E.ASM_WSDL_INTERFACE if attribute == "interface" else E.ASM_WSDL_CALLBACK
        parsed = parse_wsdl_target(target)
        if parsed is None:
            self.problems.append(Problem(code, f"interface.wsdl @{attribute} {target!r} is not of the form "
                                         "'namespace#wsdl.porttype(Name)' (or 'namespace#wsdl.interface(Name)')",
                                         where.path, where.line))
            return None
        ns, name = parsed
        index = self._wsdl_index()
        found = index.get(f"{{{ns}}}{name}")
        if found is None:
            near = [k.partition("}")[2] for k in index if k.startswith(f"{{{ns}}}")]
            hint = f"; that namespace has: {', '.join(sorted(near)[:LISTED])}" if near else ""
            self.problems.append(Problem(code, f"interface.wsdl @{attribute}: no WSDL portType {name!r} in "
                                         f"namespace {ns!r} in the contribution{hint}", where.path, where.line))
        return found

    def _wsdl_index(self) -> dict[str, InterfaceInfo]:
        if self._wsdl is None:
            self._wsdl = {}
            callbacks: dict[str, tuple[str, Problem]] = {}
            for file, root, problems in self._parse_all("*.wsdl"):
                self.problems.extend(problems)
                if root is not None:
                    shown = str(Path(self.root_file).parent / file.name)
                    types, declared = read_port_types(root, shown)
                    self._wsdl.update(types)
                    callbacks.update(declared)
            for qname, (cb, missing) in callbacks.items():  # sca:callback="QName" on a portType
                if cb in self._wsdl:
                    self._wsdl[qname] = dataclasses.replace(self._wsdl[qname], callback=self._wsdl[cb])
                else:
                    self.problems.append(missing)
        return self._wsdl


#: What an ``interface.wsdl`` @interface (or @callbackInterface) may say.
_WSDL_TARGET = re.compile(r"(?P<ns>[^#\s]*)#wsdl\.(?:porttype|interface)\((?P<name>[^()\s]+)\)")

#: Names an error message lists, at most.
LISTED = 20


def parse_wsdl_target(target: str) -> tuple[str, str] | None:
    """``(namespace, name)`` of ``ns#wsdl.porttype(Name)`` or ``ns#wsdl.interface(Name)``; None otherwise."""
    m = _WSDL_TARGET.fullmatch(target.strip())
    return (m["ns"], m["name"]) if m else None


def read_port_types(root: etree._Element, path: str = "<memory>"
                    ) -> tuple[dict[str, InterfaceInfo], dict[str, tuple[str, Problem]]]:
    """WSDL 1.1 ``portType`` s of a parsed ``definitions`` element, by Clark QName, and the
    callback portType each names with an ``sca:callback`` attribute (Clark QName, and the
    problem to report if it names nothing).

    An operation with an ``input`` and no ``output`` is one-way.
    """
    tns = root.get("targetNamespace", "")
    out: dict[str, InterfaceInfo] = {}
    callbacks: dict[str, tuple[str, Problem]] = {}
    for pt in root.iterchildren(f"{{{WSDL_NS}}}portType"):
        ops: dict[str, Operation] = {}
        for op in pt.iterchildren(f"{{{WSDL_NS}}}operation"):
            has_out = op.find(f"{{{WSDL_NS}}}output") is not None
            ops[op.get("name", "")] = Operation(op.get("name", ""), oneway=not has_out, returns_value=has_out)
        qname = f"{{{tns}}}{pt.get('name', '')}"
        out[qname] = InterfaceInfo(pt.get("name", ""), ops, remotable=True)
        for sca in (SCA11_NS, SCA10_NS):
            raw = pt.get(f"{{{sca}}}callback")
            if raw is None:
                continue
            prefix, _, local = raw.strip().rpartition(":")
            ns = pt.nsmap.get(prefix) if prefix else tns
            callbacks[qname] = (f"{{{ns}}}{local}", Problem(
                E.SCART_WSDL, f"portType {pt.get('name', '')!r}: sca:callback {raw!r} names no portType in the "
                "contribution", path, pt.sourceline or 0))
    return out, callbacks

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
