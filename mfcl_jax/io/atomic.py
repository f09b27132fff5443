"""Safe output: checked targets and atomic writes.

``check_output`` is what a command calls right after parsing its arguments, before any heavy
work: it refuses a target that is one of the run's inputs (or, for a folder, one that holds
an input), a symbolic link, a device, FIFO or socket, a folder where a file is expected (or
the reverse), and a target whose folder cannot be created or written. ``atomic_write``
repeats the per-file checks and writes through a temporary file in the target folder,
renamed into place: a reader never sees a half-written file, a failure leaves nothing behind,
and the file gets the permissions of an ordinary new file (``0o666`` less the umask;
``mkstemp`` alone would leave ``0o600``).

Only the last component of the output path may not be a link: replacing a link would
either redirect the write to wherever it points or silently drop the link. Folders on the
way may be links (a home folder often is one).
"""

from __future__ import annotations

import os
import stat
import tempfile
from pathlib import Path

from mfcl_jax.io.errors import DataError

__all__ = ["atomic_write", "atomic_write_text", "check_output", "publish_mode"]


def _error(msg: str):
    return DataError(msg)


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def publish_mode(path, folder: bool = False) -> None:
    """Gives a freshly made temporary file (or folder) the mode a plain ``open`` (``mkdir``)
    would have given it under the current umask."""
    os.chmod(path, (0o777 if folder else 0o666) & ~_umask())


def _same(a: Path, b: Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return a.resolve() == b.resolve()


def _inside(child: Path, parent: Path) -> bool:
    c, p = child.resolve(), parent.resolve()
    return c == p or p in c.parents


def _check_target(path: Path, folder: bool) -> None:
    what = "folder" if folder else "file"
    if path.is_symlink():
        raise _error(
            f"{path}: output is a symbolic link (to {os.readlink(path)}); "
            f"refusing to replace it, give the real {what} name"
        )
    try:
        mode = path.stat().st_mode
    except (FileNotFoundError, NotADirectoryError):  # the folder check below says why
        return
    except OSError as e:
        raise _error(f"{path}: cannot inspect the output ({e.strerror})") from None
    if stat.S_ISDIR(mode) and not folder:
        raise _error(f"{path}: output is a folder, expected a file name")
    if stat.S_ISREG(mode) and folder:
        raise _error(f"{path}: output is a file, expected a folder name")
    if not (stat.S_ISREG(mode) or stat.S_ISDIR(mode)):
        raise _error(f"{path}: output is a device, FIFO or socket; refusing to write onto it")


def _check_folder_writable(path: Path) -> None:
    parent = path.parent
    while not parent.exists():
        if parent.is_symlink():  # a dangling link on the way
            raise _error(f"{path}: output folder {parent} is a dangling symbolic link")
        parent = parent.parent
    if not parent.is_dir():
        raise _error(f"{path}: {parent} is not a folder, the output cannot be created there")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise _error(f"{path}: permission denied: folder {parent} is not writable")


def check_output(path, inputs=(), folder: bool = False) -> Path:
    """Checks that ``path`` can safely receive this run's output, before the run starts.

    Args:
        path: the output file (or folder, with ``folder=True``).
        inputs: paths the run reads (files or folders; ``None`` entries are skipped).
        folder: the output is a folder that will be replaced as a whole.

    Returns:
        ``path`` as a ``Path``.

    Raises:
        DataError: naming the output and the reason: it is an input file of the run, lies
            inside an input folder, holds an input (folder outputs), is a symbolic link, a
            device/FIFO/socket, the wrong kind (file vs folder), or its folder cannot be
            written.
    """
    path = Path(path)
    _check_target(path, folder)
    for src in inputs:
        if src is None:
            continue
        src = Path(src)
        if src.is_dir():
            if _inside(path, src):
                raise _error(f"{path}: output lies inside the input folder {src}")
        elif _same(path, src):
            raise _error(f"{path}: output is an input of this run ({src})")
        if folder and _inside(src, path):
            raise _error(f"{path}: output folder holds the input {src}; it would be replaced")
    _check_folder_writable(path)
    return path


def atomic_write(path, data: str | bytes) -> Path:
    """Writes ``data`` (text or bytes) to ``path`` atomically; returns the path.

    Raises:
        DataError: the target is a symbolic link, a folder, a device or FIFO, or cannot be
            written (permission denied, no space, ...).
    """
    path = Path(path)
    _check_target(path, folder=False)
    tmp = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
        with os.fdopen(fd, "wb" if isinstance(data, bytes) else "w") as fh:
            fh.write(data)
        publish_mode(tmp)
        os.replace(tmp, path)
    except OSError as e:
        raise _error(f"{path}: cannot write ({e.strerror or e})") from None
    finally:
        if tmp is not None and os.path.exists(tmp):
            os.unlink(tmp)
    return path


def atomic_write_text(path, text: str) -> Path:
    """Writes ``text`` to ``path`` through a temporary file renamed into place."""
    return atomic_write(path, text)
