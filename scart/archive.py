"""Contributions packed as ZIP archives (SCA Assembly 1.1, §12.1: a contribution may be
a ZIP file as well as a folder; a ``.jar`` is one too).

:func:`unpack` extracts an archive into a private temporary folder (``mkdtemp``: mode
0700, removed when the returned :class:`~tempfile.TemporaryDirectory` is cleaned up or
collected) and nowhere else, under the limits a property's ``@file`` has: the archive
at most :data:`MAX_ARCHIVE_BYTES`, at most :data:`MAX_ENTRIES` entries, each at most
:data:`MAX_ENTRY_BYTES` and all together at most :data:`MAX_TOTAL_BYTES` once
unpacked (counted while writing, never trusted from the archive's header), at most
:data:`MAX_DEPTH` folders deep; an entry whose path is absolute, has ``..``, a drive or
a backslash, or that is a link, is refused — the archive is then not used at all.
"""

from __future__ import annotations

import os
import stat
import tempfile
import zipfile
from pathlib import Path, PurePosixPath

__all__ = ["MAX_ARCHIVE_BYTES", "MAX_ENTRIES", "MAX_ENTRY_BYTES", "MAX_TOTAL_BYTES", "ArchiveError", "is_archive",
           "unpack"]

MAX_ARCHIVE_BYTES = 64 << 20  #: size bound of the archive file itself
MAX_ENTRIES = 10_000  #: entries (files and folders) an archive may hold
MAX_ENTRY_BYTES = 8 << 20  #: one entry, unpacked (the bound of any XML file scart reads)
MAX_TOTAL_BYTES = 256 << 20  #: every entry together, unpacked
MAX_DEPTH = 16  #: folders an entry may be nested in
_CHUNK = 64 << 10


class ArchiveError(ValueError):
    """An archive cannot be used: unreadable, over a limit, or an entry that would escape."""


def is_archive(path: Path) -> bool:
    """Is ``path`` a regular file holding a ZIP archive (``.zip``, ``.jar``...)?"""
    try:
        return path.is_file() and zipfile.is_zipfile(path)
    except OSError:
        return False


def unpack(archive: Path) -> tempfile.TemporaryDirectory[str]:
    """Extract ``archive`` into a fresh private temporary folder (see the module
    docstring); the caller keeps the returned object alive as long as the folder is
    used. Raises :class:`ArchiveError` saying which limit or entry; nothing is left
    behind then."""
    try:  # opened without blocking (a FIFO swapped in must not hang), then checked on the open file
        fd = os.open(archive, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except OSError as exc:
        raise ArchiveError(f"cannot read {archive}: {exc.strerror or exc}") from None
    with os.fdopen(fd, "rb") as fh:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise ArchiveError(f"{archive} is not a regular file")
        if info.st_size > MAX_ARCHIVE_BYTES:
            raise ArchiveError(f"{archive} is {info.st_size} bytes, over the {MAX_ARCHIVE_BYTES} bytes bound")
        target = tempfile.TemporaryDirectory(prefix="scart-contribution-")
        try:
            with zipfile.ZipFile(fh) as zf:
                _extract(zf, Path(target.name), archive)
        except (zipfile.BadZipFile, OSError, RuntimeError, NotImplementedError) as exc:
            target.cleanup()
            raise ArchiveError(f"{archive} cannot be read as a ZIP archive: {exc}") from None
        except ArchiveError:
            target.cleanup()
            raise
    return target


def _extract(zf: zipfile.ZipFile, root: Path, archive: Path) -> None:
    infos = zf.infolist()
    if len(infos) > MAX_ENTRIES:
        raise ArchiveError(f"{archive} has {len(infos)} entries, over the {MAX_ENTRIES} entries bound")
    total = 0
    for info in infos:
        parts = _safe_parts(info, archive)
        dest = root.joinpath(*parts)
        if info.is_dir():
            dest.mkdir(parents=True, exist_ok=True)
            continue
        dest.parent.mkdir(parents=True, exist_ok=True)
        total += _copy(zf, info, dest, archive, MAX_TOTAL_BYTES - total)


def _safe_parts(info: zipfile.ZipInfo, archive: Path) -> tuple[str, ...]:
    """The path of an entry as folder names, refusing one that could land outside."""
    name = info.filename
    mode = info.external_attr >> 16
    if stat.S_ISLNK(mode):
        raise ArchiveError(f"{archive}: entry {name!r} is a link (links are refused)")
    path = PurePosixPath(name)
    parts = tuple(p for p in path.parts if p not in ("", "."))
    if (path.is_absolute() or "\\" in name or ".." in parts or not parts or ":" in parts[0]
            or "\x00" in name):
        raise ArchiveError(f"{archive}: entry {name!r} would land outside the contribution")
    if len(parts) > MAX_DEPTH + 1:
        raise ArchiveError(f"{archive}: entry {name!r} is more than {MAX_DEPTH} folders deep")
    return parts


def _copy(zf: zipfile.ZipFile, info: zipfile.ZipInfo, dest: Path, archive: Path, left: int) -> int:
    """Write one entry, counting what is really unpacked; the bytes written."""
    written = 0
    try:
        out = open(dest, "xb")  # noqa: SIM115 - "x": an entry named twice is refused
    except FileExistsError:
        raise ArchiveError(f"{archive}: entry {info.filename!r} is there twice") from None
    with zf.open(info) as src, out:
        while chunk := src.read(_CHUNK):
            written += len(chunk)
            if written > MAX_ENTRY_BYTES:
                raise ArchiveError(f"{archive}: entry {info.filename!r} is over the {MAX_ENTRY_BYTES} bytes bound")
            if written > left:
                raise ArchiveError(f"{archive}: its entries are over the {MAX_TOTAL_BYTES} bytes bound together")
            out.write(chunk)
    return written
