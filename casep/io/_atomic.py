"""Safe file output: atomic writes that respect links, special files and modes; early checks.

:func:`atomic_open` writes a regular file through a temporary file beside it and a rename,
so the file appears whole or not at all. It writes *through* what the rename would destroy:
a symbolic link is followed (its target is replaced, the link stays), a FIFO, character
device or socket (``/dev/stdout``, a named pipe) is opened and written directly, and an
existing file keeps its permission bits.

:func:`check_output` and :func:`check_output_dir` are called by each command before any
work, so that a bad output path fails in a second instead of after the computation, and an
output that is one of the command's inputs (the flight would be overwritten) is refused.

:func:`output_group` makes several outputs appear together: inside it, every file that
:func:`atomic_open` writes stays a temporary file until the block ends without error, then all
are renamed into place; on an error none is (a failed second output leaves no first one). A
failed write names its file (a full disk: ``cannot write out.json: No space left on device``).
"""

from __future__ import annotations

import contextlib
import contextvars
import os
import re
import stat
import sys
import tempfile
from pathlib import Path
from typing import IO, Iterable, Iterator

__all__ = ["atomic_open", "output_group", "read_output", "scratch_files", "check_output", "check_output_dir",
           "check_outputs"]

PathLike = str | os.PathLike


def _own_descriptor(path: Path) -> int | None:
    """The descriptor number when `path` leads (through links) to ``/proc/self/fd/N`` of this
    process, as ``/dev/stdout`` and ``/dev/fd/N`` do; else None."""
    own = re.compile(rf"^/proc/(?:self|{os.getpid()})/fd/(\d+)$")
    p = path.absolute()
    for _ in range(40):  # link hops, as the kernel's limit
        p = Path(os.path.realpath(p.parent)) / p.name  # resolve the folders (/dev/fd -> /proc/<pid>/fd)
        m = own.match(str(p))
        if m:
            return int(m.group(1))
        if not p.is_symlink():
            return None
        p = p.parent / os.readlink(p)
    return None


def _direct(path: Path) -> int | str | None:
    """How to write `path` without a rename: a descriptor of this process to duplicate
    (``/dev/stdout``), "open" for a FIFO, device or socket, or None (atomic replace)."""
    fd = _own_descriptor(path)
    if fd is not None:
        return fd
    try:
        st = os.stat(path)  # follows links
    except (FileNotFoundError, NotADirectoryError):
        return None
    return None if stat.S_ISREG(st.st_mode) or stat.S_ISDIR(st.st_mode) else "open"


def _new_file_mode(target: Path) -> int:
    """Permission bits for the written file: the existing file's, else ``0o666 & ~umask``."""
    try:
        return stat.S_IMODE(os.stat(target).st_mode)
    except (FileNotFoundError, NotADirectoryError):
        umask = os.umask(0)
        os.umask(umask)
        return 0o666 & ~umask


#: The pending renames ``(temporary, target)`` of the innermost :func:`output_group`, or None.
_GROUP: contextvars.ContextVar[list | None] = contextvars.ContextVar("casep_output_group", default=None)


@contextlib.contextmanager
def output_group() -> Iterator[None]:
    """All files :func:`atomic_open` writes inside the block appear together when it ends without
    error, or none of them (their temporary files are removed).

    The renames happen one after the other at the end, after every output has been written in
    full; a FIFO or device output (``/dev/stdout``) is written directly and cannot wait.
    """
    outer = _GROUP.get()
    pending: list[tuple[str, Path]] = []
    token = _GROUP.set(pending)
    try:
        yield
    except BaseException:
        _GROUP.reset(token)
        for tmp, _ in pending:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
        raise
    _GROUP.reset(token)
    if outer is not None:  # nested: the outer group renames them
        outer.extend(pending)
        return
    for k, (tmp, target) in enumerate(pending):
        try:
            os.replace(tmp, target)
        except OSError as exc:
            for t, _ in pending[k:]:
                with contextlib.suppress(OSError):
                    os.unlink(t)
            raise OSError(exc.errno, f"cannot write {target}: {exc.strerror}") from exc


@contextlib.contextmanager
def scratch_files() -> Iterator[None]:
    """Files written inside this block are not part of the enclosing :func:`output_group` (scratch
    files in a temporary folder, gone before the group ends): each is renamed at once."""
    token = _GROUP.set(None)
    try:
        yield
    finally:
        _GROUP.reset(token)


def read_output(path: PathLike) -> bytes:
    """The bytes of a file this process wrote with :func:`atomic_open`, also while its
    :func:`output_group` is still pending (the report embeds the figures written before it)."""
    target = Path(os.path.realpath(path))
    for tmp, t in reversed(_GROUP.get() or []):
        if t == target:
            return Path(tmp).read_bytes()
    return Path(path).read_bytes()


@contextlib.contextmanager
def atomic_open(path: PathLike, *, binary: bool = False) -> Iterator[IO]:
    """Open `path` for (text or binary) writing so that it appears whole or not at all.

    A regular (or new) file: the data go to a temporary file in the target's folder,
    renamed over the target when the block ends without error (inside an
    :func:`output_group`: when the group ends); on error the temporary file is removed and the
    target is left as it was. A symbolic link is resolved first, so the link stays and its
    target is replaced. An existing file keeps its permission bits; a new one gets
    ``0o666 & ~umask``. A FIFO, character device or socket (``/dev/stdout``, a named pipe) is
    written directly: a rename would replace the node with a regular file. An OSError while
    writing (a full disk) names `path`.
    """
    path = Path(path)
    direct = _direct(path)
    if direct is not None:
        # Our own descriptor is duplicated (shares its offset, is never truncated); a FIFO or
        # device is opened. What this process printed before goes first.
        sys.stdout.flush()
        sys.stderr.flush()
        target = os.dup(direct) if isinstance(direct, int) else path
        mode = "wb" if binary else "w"
        try:
            with (open(target, mode) if binary else open(target, mode, encoding="utf-8", newline="\n")) as fh:
                yield fh
        except OSError as exc:
            raise OSError(exc.errno, f"cannot write {path}: {exc.strerror}") from exc
        return
    target = Path(os.path.realpath(path))  # through symbolic links (also a dangling one)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    try:
        opened = os.fdopen(fd, "wb") if binary else os.fdopen(fd, "w", encoding="utf-8", newline="\n")
        try:
            with opened as fh:
                yield fh
        except OSError as exc:  # ENOSPC and friends: say which output
            raise OSError(exc.errno, f"cannot write {path}: {exc.strerror}") from exc
        os.chmod(tmp, _new_file_mode(target))
        group = _GROUP.get()
        if group is not None:
            group.append((tmp, target))  # renamed when the group ends
        else:
            os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def _same_file(a: Path, b: Path) -> bool:
    """True when `a` and `b` name the same file (same inode, or same resolved path)."""
    with contextlib.suppress(OSError):
        return os.path.samefile(a, b)
    return os.path.realpath(a) == os.path.realpath(b)


def _writable_dir(folder: Path, option: str, shown: PathLike) -> None:
    if not folder.exists():
        raise ValueError(f"{option} {shown}: folder {folder} does not exist")
    if not folder.is_dir():
        raise ValueError(f"{option} {shown}: {folder} is not a folder")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise ValueError(f"{option} {shown}: folder {folder} is not writable")


def check_output(path: PathLike, option: str, *, inputs: Iterable[PathLike | None] = ()) -> Path:
    """Check before any work that `path` can be written and is none of `inputs`.

    Parameters
    ----------
    path : path-like
        The output file.
    option : str
        The option that names it (``"--json"``), for the message.
    inputs : iterable of path-like or None
        The command's input files (None entries are skipped).

    Returns
    -------
    Path
        `path`.

    Raises
    ------
    ValueError
        The output is an input (naming both), is a folder, or its folder is missing or
        not writable; a special file (FIFO, device) that cannot be opened for writing.
    """
    p = Path(path)
    for inp in inputs:
        if inp is not None and Path(inp).exists() and _same_file(p, Path(inp)):
            raise ValueError(f"{option} {path} is the input file {inp}: refusing to overwrite it")
    if p.is_dir():
        raise ValueError(f"{option} {path}: is a folder, not a file")
    direct = _direct(p)
    if isinstance(direct, int):
        return p
    if direct is not None:
        if not os.access(p, os.W_OK):
            raise ValueError(f"{option} {path}: not writable")
        return p
    target = Path(os.path.realpath(p))
    _writable_dir(target.parent, option, path)
    if target.exists() and not os.access(target, os.W_OK):
        # The rename would succeed in a writable folder, but a read-only file says "keep me".
        raise ValueError(f"{option} {path}: file is read-only")
    return p


def check_output_dir(path: PathLike, option: str) -> Path:
    """Check before any work that folder `path` exists and is writable, or can be created.

    The folder is not created here (nothing is made if the computation fails); create it
    with ``Path(path).mkdir(parents=True, exist_ok=True)`` just before writing.
    """
    p = Path(path)
    if p.exists():
        if not p.is_dir():
            raise ValueError(f"{option} {path}: exists and is not a folder")
        _writable_dir(p, option, path)
        return p
    parent = p.absolute().parent
    while not parent.exists():  # the nearest existing ancestor must let us create the rest
        parent = parent.parent
    _writable_dir(parent, option, path)
    return p


def check_outputs(files: dict[str, PathLike | None], *, inputs: Iterable[PathLike | None] = (),
                  folders: dict[str, PathLike | None] | None = None) -> None:
    """Check every output of a command before any work (:func:`check_output`,
    :func:`check_output_dir`), and that no two options write the same file.

    Parameters
    ----------
    files : dict
        ``{option: path or None}`` of output files (None: option not given).
    inputs : iterable of path-like or None
        The command's input files; an output that is one of them is refused.
    folders : dict, optional
        ``{option: path or None}`` of output folders (created later by the command).
    """
    in_paths = [Path(i) for i in inputs if i is not None]
    given = [(opt, Path(p)) for opt, p in files.items() if p is not None]
    for opt, p in given:
        check_output(p, opt, inputs=in_paths)
    for i, (oa, pa) in enumerate(given):
        for ob, pb in given[i + 1:]:
            if _direct(pa) is None and _same_file(pa, pb):  # a device or pipe may take both
                raise ValueError(f"{oa} and {ob} both name {pa}: give different files")
    for opt, folder in (folders or {}).items():
        if folder is not None:
            check_output_dir(folder, opt)
