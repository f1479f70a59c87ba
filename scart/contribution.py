"""Contributions: where a composite's artifacts come from (SCA Assembly 1.1, §11).

A contribution is a folder: the ``.composite``, ``.wsdl``, ``.xsd`` and ``.componentType``
files in it and its subfolders (hidden ones, ``__pycache__``, virtual environments, build
output and nested contributions — a subfolder with its own ``META-INF`` metadata — left
out; at most :data:`MAX_WALK_DEPTH` deep and :data:`MAX_WALK_FILES` files) and its Python
modules. Its optional
``META-INF/sca-contribution.xml`` lists the deployable composites and the XML namespaces
it imports from and exports to other contributions::

    <contribution xmlns="http://docs.oasis-open.org/ns/opencsa/sca/200912" xmlns:app="urn:app">
      <deployable composite="app:Robot"/>
      <import namespace="urn:shared" location="../shared"/>
      <export namespace="urn:app"/>
    </contribution>

A root composite is resolved in its folder's contribution, the other contributions given
(``scart run --contribution DIR``, ``Runtime.from_file(..., contributions=[...])``) and
those its imports locate (``@location``, relative to the importing folder). A QName — a
composite, a WSDL portType, an XML Schema type or element — in a namespace a contribution
imports is looked up in the contributions exporting it, in import order, then — when none
of them holds it — in the importing contribution itself (ASM12022, ASM12023); an import
no contribution exports is an error (ASM12021). Other
QNames are looked up in the contribution itself. A contribution without metadata sees its
own artifacts first, then whatever the others export. Every contribution folder is on
``sys.path`` (the root's first), so implementation classes are found across them as on a
class path; a module of the same name imported earlier from elsewhere is replaced by the
root folder's own.

A composite that cannot be parsed matters only if something refers to a QName it might
hold (its problems are then reported).
"""

from __future__ import annotations

import dataclasses
import fnmatch
import importlib
import logging
import os
import sys
import tempfile
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType

from lxml import etree

from scart import errors as E
from scart.api import InterfaceInfo
from scart.archive import ArchiveError, is_archive, unpack
from scart.errors import Problem
from scart.model import SCA10_NS, SCA11_NS, ComponentTypeFile, Composite, Location
from scart.schemas import SchemaSet
from scart.scdl import Loader, did_you_mean, parse_xml
from scart.wsdl import (
    Need, WsdlTypes, missing_schemas, parse_wsdl_target, port_type_needs, read_port_types, wsdl_types,
)

METADATA = Path("META-INF") / "sca-contribution.xml"
log = logging.getLogger(__name__)
MAX_CONTRIBUTIONS = 64  #: contributions one composite may be resolved in (given and located)


@dataclass
class Metadata:
    """What ``META-INF/sca-contribution.xml`` says (``present`` False without one)."""

    present: bool = False
    deployables: list[tuple[str, Location]] = field(default_factory=list)  #: Clark QNames
    imports: list[tuple[str, str | None, Location]] = field(default_factory=list)  #: (namespace, location)
    exports: list[str] = field(default_factory=list)


#: The children of ``<contribution>`` and the attributes each may carry.
_METADATA_CHILDREN: MappingProxyType[str, tuple[str, ...]] = MappingProxyType({
    "deployable": ("composite",), "import": ("namespace", "location"), "export": ("namespace",)})


def deployable_of(folder: Path) -> tuple[str | None, list[Problem]]:
    """The composite file to run for a contribution folder: its one deployable (from
    ``META-INF/sca-contribution.xml``); else None and why."""
    contribution = Contribution(str(folder / METADATA.name))
    deployables = contribution.deployables()
    meta = contribution.folders[0].metadata
    if len(deployables) == 1:
        return contribution.find_deployable(*deployables[0]), contribution.problems
    where = str(folder / METADATA)
    if not meta.present:
        message = f"{folder} is a folder without {METADATA}: name a .composite file, or list it there as <deployable>"
    elif not deployables:
        message = f"{where} lists no <deployable> composite: name a .composite file"
    else:
        names = ", ".join(q.partition("}")[2] for q, _ in deployables)
        message = f"{where} lists {len(deployables)} deployable composites ({names}): name one .composite file"
    return None, [*contribution.problems, Problem(E.ASM_UNRESOLVED, message, where, 0)]


def read_metadata(folder: Path, problems: list[Problem], shown: Path | None = None) -> Metadata:
    """The metadata of the contribution in ``folder`` (problems, with ASM12027 for a file
    that does not follow the contribution schema, go to ``problems``)."""
    path = folder / METADATA
    if not path.is_file():
        return Metadata()
    where = str((shown or folder) / METADATA)
    read: list[Problem] = []
    root = parse_xml(str(path), read)
    problems.extend(dataclasses.replace(p, path=where) for p in read)
    meta = Metadata(present=True)
    if root is None:
        return meta

    def problem(message: str, el: etree._Element) -> None:
        problems.append(Problem(E.ASM_CONTRIBUTION_SCHEMA, message, where, el.sourceline or 0))

    if etree.QName(root).text not in (f"{{{SCA11_NS}}}contribution", f"{{{SCA10_NS}}}contribution"):
        problem(f"the root element must be an SCA <contribution>, not <{etree.QName(root).localname}>", root)
        return meta
    for child in root.iterchildren(tag=etree.Element):
        local = etree.QName(child).localname
        if local in ("documentation", "extensions") or local.startswith(("import.", "export.")):
            continue  # import.java, export.resource...: another language's artifacts (the importBase group)
        allowed = _METADATA_CHILDREN.get(local)
        if allowed is None or etree.QName(child).namespace not in (SCA11_NS, SCA10_NS):
            problem(f"unknown element <{local}> inside <contribution>{did_you_mean(local, _METADATA_CHILDREN)}", child)
            continue
        for attr in child.attrib:
            if not attr.startswith("{") and attr not in allowed:
                problem(f"<{local}> has no attribute {attr!r}{did_you_mean(attr, allowed)}", child)
        loc = Location(path=where, line=child.sourceline or 0)
        if local == "deployable":
            raw = (child.get("composite") or "").strip()
            prefix, _, name = raw.rpartition(":")
            ns = child.nsmap.get(prefix) if prefix else ""
            if not name or ns is None:
                problem(f"<deployable> needs @composite, the QName of a composite (got {raw!r})", child)
                continue
            meta.deployables.append((f"{{{ns}}}{name}", loc))
        elif not child.get("namespace"):
            problem(f"<{local}> needs a @namespace", child)
        elif local == "import":
            meta.imports.append((child.get("namespace", ""), child.get("location"), loc))
        else:
            meta.exports.append(child.get("namespace", ""))
    return meta


#: How deep, and over how many files, a contribution folder is searched for artifacts.
MAX_WALK_DEPTH = 8
MAX_WALK_FILES = 20_000
_NOT_ARTIFACTS = frozenset({"__pycache__", "node_modules", "build", "dist", "site-packages"})


class _Folder:
    """One contribution: its folder, how it is shown, its metadata and lazy indices."""

    def __init__(self, path: Path, shown: Path, metadata: Metadata, origin: Path | None = None,
                 label: Path | None = None) -> None:
        self.path = path
        self.shown = shown
        self.metadata = metadata
        self.origin = origin or path  # what a @location names: the folder, or the ZIP archive it was unpacked from
        self.label = label or shown  # how the user names it (the base of its imports' @location)
        self.composites: dict[str, str] | None = None  # QName -> file (as shown)
        self.same_qname: dict[str, list[str]] = {}  # QName -> every file declaring it (when more than one)
        self.unparsed: list[Problem] = []  # problems of composites that could not be parsed
        self.wsdl: dict[str, InterfaceInfo] | None = None
        self.wsdl_callbacks: dict[str, tuple[str, Problem]] = {}
        self.wsdl_needs: dict[str, tuple[list[Need], WsdlTypes, str]] = {}  # portType -> what its messages name
        self._files: list[Path] | None = None
        self.given = True  # given by the user (else found through an import's @location)

    def files(self, pattern: str) -> list[Path]:
        """The contribution's files matching ``pattern`` (a name glob), sorted; see the module docstring."""
        if self._files is None:
            self._files = []
            for where, folders, names in os.walk(self.path):  # links to folders are not followed
                here = Path(where)
                deep = len(here.relative_to(self.path).parts) >= MAX_WALK_DEPTH
                folders[:] = [] if deep else sorted(
                    d for d in folders if not d.startswith(".") and d not in _NOT_ARTIFACTS
                    and not (here / d / "pyvenv.cfg").exists() and not (here / d / METADATA).exists())
                self._files += [here / n for n in names if (here / n).is_file()]
                if len(self._files) >= MAX_WALK_FILES:
                    log.warning("contribution %s: more than %d files; the rest are not searched", self.shown,
                                MAX_WALK_FILES)
                    break
            self._files.sort()
        return [f for f in self._files if fnmatch.fnmatchcase(f.name, pattern)]

    def shown_file(self, file: Path) -> str:
        """A file of this contribution as the user sees it (relative to how the folder is shown)."""
        return str(self.shown / file.relative_to(self.path))

    def exports(self, ns: str) -> bool:
        return ns in self.metadata.exports


class Contribution:
    """The contributions a root composite is resolved in (see the module docstring).
    Not thread-safe (loading is single-threaded)."""

    def __init__(self, root_file: str, is_element: Callable[[str], bool] = lambda name: False,
                 contributions: Sequence[str | Path] = (),
                 root_archive: tuple[Path, tempfile.TemporaryDirectory[str]] | None = None) -> None:
        self.root_file = root_file
        self.folder = Path(root_file).resolve().parent
        self.is_element = is_element  # which <scart:NAME> composite children are extension elements
        self.problems: list[Problem] = []
        self.archives: dict[str, str] = {}  # unpacked folder -> how its archive is shown ("lib.zip!")
        self._unpacked: list[tempfile.TemporaryDirectory[str]] = []  # kept alive as long as this contribution
        root_shown = Path(root_file).parent
        origin = label = None
        if root_archive is not None:  # the root contribution was a ZIP archive, unpacked by the caller
            label, unpacked = root_archive
            origin = label.resolve()
            self._unpacked.append(unpacked)
            self.archives[str(self.folder)] = f"{label}!"
        self.folders = [_Folder(self.folder, root_shown, read_metadata(self.folder, self.problems, root_shown),
                                origin, label)]
        for given in contributions:
            self._add(Path(given), None)
        i = 0
        while i < len(self.folders):  # bounded: at most MAX_CONTRIBUTIONS folders are ever added
            folder = self.folders[i]
            for ns, location, loc in folder.metadata.imports:
                if location:
                    self._add(folder.label / location, loc)
            i += 1
        self._check_imports()
        self._loaded: dict[str, Composite | None] = {}  # file -> loaded once, reused (problems reported once)
        self._loading: list[str] = []
        self._schemas: SchemaSet | None = None
        self._component_types: dict[str, ComponentTypeFile | None] = {}
        self._wsdl_checked: set[str] = set()

    # --- the contributions ----------------------------------------------------------

    def _add(self, shown: Path, where: Location | None) -> _Folder | None:
        path = shown.resolve()
        for f in self.folders:
            if f.path == path or f.origin == path:
                return f
        archive = is_archive(path)
        if not path.is_dir() and not archive:
            message = f"contribution {shown}: no such folder or ZIP archive"
            self.problems.append(Problem(E.ASM_UNRESOLVED, message, where.path if where else str(shown),
                                         where.line if where else 0))
            return None
        if len(self.folders) >= MAX_CONTRIBUTIONS:
            self.problems.append(Problem(E.ASM_UNRESOLVED, f"contribution {shown}: more than {MAX_CONTRIBUTIONS} "
                                         "contributions", where.path if where else str(shown), where.line if where else 0))
            return None
        if archive:
            folder = self._unpack(shown, path, where)
            if folder is None:
                return None
        else:
            folder = _Folder(path, shown, read_metadata(path, self.problems, shown))
        folder.given = where is None
        self.folders.append(folder)
        return folder

    def _unpack(self, shown: Path, path: Path, where: Location | None) -> _Folder | None:
        """A ZIP contribution, unpacked into a private temporary folder (:mod:`scart.archive`)."""
        try:
            unpacked = unpack(path)
        except ArchiveError as exc:
            self.problems.append(Problem(E.SCART_ARCHIVE, f"contribution {shown}: {exc}",
                                         where.path if where else str(shown), where.line if where else 0))
            return None
        self._unpacked.append(unpacked)
        folder = Path(unpacked.name).resolve()
        self.archives[str(folder)] = f"{shown}!"
        return _Folder(folder, folder, read_metadata(folder, self.problems, folder), path, shown)

    def display_problem(self, problem: Problem) -> Problem:
        """``problem`` with :meth:`display` applied to its path and message."""
        if not self.archives:
            return problem
        return dataclasses.replace(problem, path=self.display(problem.path), message=self.display(problem.message))

    def display(self, text: str) -> str:
        """``text`` with the folders ZIP contributions were unpacked into named by their
        archives ("lib.zip!/parts.composite")."""
        for folder, archive in self.archives.items():
            text = text.replace(folder, archive)
        return text

    def _check_imports(self) -> None:
        for folder in self.folders:
            for ns, location, loc in folder.metadata.imports:
                if not self._exporters(folder, ns, location):
                    where = f"at {location}" if location else "among the contributions given"
                    self.problems.append(Problem(E.ASM_UNRESOLVED, f"import of namespace {ns!r}: no contribution "
                                                 f"{where} exports it", loc.path, loc.line))

    def _exporters(self, folder: _Folder, ns: str, location: str | None) -> list[_Folder]:
        if location:
            path = (folder.label / location).resolve()
            return [f for f in self.folders if (f.path == path or f.origin == path) and f.exports(ns)]
        return [f for f in self.folders if f is not folder and f.exports(ns)]

    def folder_of(self, path: str) -> _Folder:
        """The contribution a file (as shown in a location) belongs to — the innermost folder
        holding it; the root's by default."""
        file = Path(path).resolve()
        holding = [f for f in self.folders if file.is_relative_to(f.path)]
        return max(holding, key=lambda f: len(f.path.parts)) if holding else self.folders[0]

    def search(self, ns: str, where: Location) -> list[_Folder]:
        """Where a QName of namespace ``ns``, used in the file of ``where``, is looked up, in order."""
        origin = self.folder_of(where.path)
        imports = [(n, loc) for n, loc, _ in origin.metadata.imports if n == ns]
        if imports:
            found: list[_Folder] = []
            for _, location in imports:
                found += [f for f in self._exporters(origin, ns, location) if f not in found]
            return found if origin in found else [*found, origin]  # its own copy comes next
        if not origin.metadata.present:
            return [origin] + [f for f in self.folders if f is not origin and f.exports(ns)]
        return [origin]

    def deployables(self) -> list[tuple[str, Location]]:
        """The root contribution's deployable composites (Clark QNames)."""
        return list(self.folders[0].metadata.deployables)

    # --- composites -------------------------------------------------------------------

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
        """The composite called ``qname`` as seen from ``where``, loaded on first use; None if
        unknown or if using it would make a cycle (reported at ``where``)."""
        ns = qname[1:].partition("}")[0]
        folders = self.search(ns, where)
        path = None
        for folder in folders:
            path = self._composites(folder).get(qname)
            if path is not None:
                files = folder.same_qname.pop(qname, None)
                if files:
                    self.problems.append(Problem(E.SCART_DUPLICATE_COMPOSITE, f"composite {qname} is declared by "
                                                 f"several files: {', '.join(files)}; using {files[0]}",
                                                 where.path, where.line))
                break
        if path is None:
            for folder in folders:
                self.problems.extend(folder.unparsed)
                folder.unparsed = []
            return None
        if str(Path(path).resolve()) in self._loading:
            self.problems.append(Problem(E.SCART_COMPOSITE_CYCLE, f"composite {qname} refers back to itself "
                                         f"(cycle through {Path(path).name})", where.path, where.line))
            return None
        if path not in self._loaded:
            self._loaded[path] = self._load(path)
        return self._loaded[path]

    def _composites(self, folder: _Folder) -> dict[str, str]:
        if folder.composites is None:
            folder.composites = {}
            for file, root, problems in self._parse_all(folder, "*.composite"):
                if root is None:
                    folder.unparsed.extend(problems)
                    continue
                qname = f"{{{root.get('targetNamespace', '')}}}{root.get('name', '')}"
                shown = folder.shown_file(file)  # as the root's path is shown
                if qname in folder.composites:
                    folder.same_qname.setdefault(qname, [folder.composites[qname]]).append(shown)
                    continue
                folder.composites[qname] = shown
        return folder.composites

    @staticmethod
    def _parse_all(folder: _Folder, pattern: str) -> Iterator[tuple[Path, etree._Element | None, list[Problem]]]:
        """Each file of ``folder`` matching ``pattern`` (sorted), parsed: ``(file, root or
        None, its parse problems)``; the caller decides where the problems go."""
        for file in folder.files(pattern):
            problems: list[Problem] = []
            root = parse_xml(folder.shown_file(file), problems)
            yield file, root, problems

    def find_deployable(self, qname: str, where: Location) -> str | None:
        """The file of a deployable composite of the root contribution (None: reported)."""
        path = self._composites(self.folders[0]).get(qname)
        if path is None:
            self.problems.append(Problem(E.ASM_UNRESOLVED, f"deployable {qname}: no composite of that name in "
                                         f"{self.folders[0].shown}", where.path, where.line))
        return path

    # --- componentType side files -------------------------------------------------------

    def component_type(self, path: Path) -> ComponentTypeFile | None:
        """The componentType side file at ``path`` (read once), or None if there is none."""
        key = str(path)
        if key not in self._component_types:
            ct = None
            if path.is_file():
                loader = Loader(key, self.resolve, self.is_element)
                ct = loader.load_component_type()
                self.problems.extend(loader.problems)
            self._component_types[key] = ct
        return self._component_types[key]

    # --- Python -----------------------------------------------------------------------

    def import_object(self, ref: str) -> object:
        """Import ``"pkg.mod:Attr"`` with every contribution folder on ``sys.path`` (the
        root's first; see :func:`import_object`)."""
        imported = {ns for f in self.folders for ns, _, _ in f.metadata.imports}
        others = [f.path for f in self.folders[1:] if f.given or any(f.exports(ns) for ns in imported)]
        return import_object(ref, self.folder, others)  # a located folder exporting nothing wanted: not a class path

    # --- XML Schema ---------------------------------------------------------------------

    @property
    def schemas(self) -> SchemaSet:
        """The XML Schemas of every contribution (read on first use)."""
        if self._schemas is None:
            files = [file for folder in self.folders for file in folder.files("*.xsd")]
            self._schemas = SchemaSet(files, self.problems)
        return self._schemas

    # --- WSDL ---------------------------------------------------------------------------

    def wsdl_interface(self, target: str, where: Location, attribute: str = "interface") -> InterfaceInfo | None:
        """The portType named by ``ns#wsdl.porttype(Name)`` (SCA 1.1, WSDL 1.1) or
        ``ns#wsdl.interface(Name)`` (SCA 1.0, WSDL 2.0); None (problem recorded) if the form
        is wrong or no ``.wsdl`` file the composite sees declares it."""
        code = E.ASM_WSDL_INTERFACE if attribute == "interface" else E.ASM_WSDL_CALLBACK
        parsed = parse_wsdl_target(target)
        if parsed is None:
            self.problems.append(Problem(code, f"interface.wsdl @{attribute} {target!r} is not of the form "
                                         "'namespace#wsdl.porttype(Name)' (or 'namespace#wsdl.interface(Name)')",
                                         where.path, where.line))
            return None
        ns, name = parsed
        near: list[str] = []
        for folder in self.search(ns, where):
            index = self._wsdl_index(folder)
            found = index.get(f"{{{ns}}}{name}")
            if found is not None:
                self._check_wsdl_schemas(folder, f"{{{ns}}}{name}")
                return found
            near += [k.partition("}")[2] for k in index if k.startswith(f"{{{ns}}}")]
        hint = f"; that namespace has: {', '.join(sorted(near)[:LISTED])}{did_you_mean(name, near)}" if near else ""
        self.problems.append(Problem(code, f"interface.wsdl @{attribute}: no WSDL portType {name!r} in "
                                     f"namespace {ns!r} in the contribution{hint}", where.path, where.line))
        return None

    def _wsdl_index(self, folder: _Folder) -> dict[str, InterfaceInfo]:
        if folder.wsdl is None:
            folder.wsdl = {}
            callbacks: dict[str, tuple[str, Problem]] = {}
            for file, root, problems in self._parse_all(folder, "*.wsdl"):
                self.problems.extend(problems)
                if root is not None:
                    types, declared = read_port_types(root, folder.shown_file(file))
                    folder.wsdl.update(types)
                    callbacks.update(declared)
                    schemas = wsdl_types(root)
                    for qname, needs in port_type_needs(root).items():
                        folder.wsdl_needs[qname] = (needs, schemas, folder.shown_file(file))
            for qname, (cb, missing) in callbacks.items():  # sca:callback="QName" on a portType
                if cb in folder.wsdl:
                    folder.wsdl[qname] = dataclasses.replace(folder.wsdl[qname], callback=folder.wsdl[cb])
                else:
                    self.problems.append(missing)
        return folder.wsdl

    def _check_wsdl_schemas(self, folder: _Folder, qname: str) -> None:
        """The elements and types the messages of portType ``qname`` need are declared
        (see :mod:`scart.wsdl`); checked once per portType."""
        if qname in self._wsdl_checked or qname not in folder.wsdl_needs:
            return
        self._wsdl_checked.add(qname)
        needs, types, path = folder.wsdl_needs[qname]
        schemas = self.schemas
        names = {file.name for f in self.folders for file in f.files("*.xsd")}

        def known(what: str, name: str) -> bool:
            return name in schemas.elements if what == "element" else schemas.kind(name) is not None

        self.problems.extend(missing_schemas(needs, types, known, names.__contains__, path,
                                             qname.partition("}")[2]))


#: Names an error message lists, at most.
LISTED = 20


def import_object(ref: str, folder: Path, others: Sequence[Path] = ()) -> object:
    """Import ``"pkg.mod:Attr"`` with ``folder`` first on ``sys.path``, then ``others``.

    Raises ``ImportError``/``AttributeError``/``ValueError`` (callers turn them into problems).
    """
    module_name, sep, attr = ref.partition(":")
    if not sep or not module_name or not attr:
        raise ValueError(f"{ref!r} is not of the form 'package.module:Class'")
    wanted = [str(folder), *(str(o) for o in others)]
    if sys.path[:len(wanted)] != wanted:
        for entry in wanted:
            while entry in sys.path:
                sys.path.remove(entry)
        sys.path[0:0] = wanted
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
