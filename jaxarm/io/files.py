"""Output files: checked before any work, and written whole or not at all.

``output_file`` and ``output_folder`` fail at once, naming the field or flag, where a long run
would otherwise fail only when it writes; ``written`` gives a temporary path beside the target
that replaces it once complete, so an error or Ctrl-C while writing leaves no half-written file.
"""

from __future__ import annotations

import contextlib
import io
import os
import pathlib
import tempfile
import threading
from typing import Iterator


def output_file(field: str, path) -> pathlib.Path:
    """``path`` as a ``Path`` that can be written: its folder exists and is writable, and it is
    not itself a folder; else a ValueError naming ``field`` (``"--json"``) and the path."""
    path = pathlib.Path(path)
    folder = path.parent
    if not folder.is_dir():
        raise ValueError(f"{field} {str(path)!r}: folder {str(folder)!r} does not exist")
    if path.is_dir():
        raise ValueError(f"{field} {str(path)!r} is a folder; give a file name")
    if _special(path):  # /dev/stdout: written in place
        if not os.access(path, os.W_OK):
            raise ValueError(f"{field} {str(path)!r} is not writable")
    elif not os.access(_target(path).parent, os.W_OK | os.X_OK):
        raise ValueError(f"{field} {str(path)!r}: folder {str(_target(path).parent)!r} is not "
                         "writable")
    else:  # what the permissions do not say (/proc, a read-only mount, root's access)
        try:
            descriptor, probe = tempfile.mkstemp(prefix=".probe.", dir=_target(path).parent)
        except OSError as error:
            raise ValueError(f"{field} {str(path)!r}: cannot create a file in folder "
                             f"{str(_target(path).parent)!r}: {error.strerror}") from None
        os.close(descriptor)
        os.unlink(probe)
    return path


def output_folder(field: str, path) -> pathlib.Path:
    """``path`` as a ``Path`` to a folder that is writable, or can be created (with its
    parents) in a writable folder; else a ValueError naming ``field`` (``"--out"``) and the
    path. Nothing is created."""
    path = pathlib.Path(path)
    existing = path
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        where = "" if existing == path else f": {str(existing)!r}"
        raise ValueError(f"{field} {str(path)!r}{where} is a file, not a folder")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise ValueError(f"{field} {str(path)!r}: folder {str(existing)!r} is not writable")
    return path


@contextlib.contextmanager
def written(path) -> Iterator[pathlib.Path]:
    """A temporary path in ``path``'s folder, with its suffix (writers pick formats by it),
    that replaces ``path`` when the block ends normally and is removed otherwise. The writer
    creates it, so it gets the permissions any new file gets. A symbolic link's target is
    replaced, not the link; a device or pipe (``/dev/stdout``) is written in place."""
    path = pathlib.Path(path)
    if _special(path):
        yield path
        return
    target = _target(path)
    temporary = target.with_name(f".{target.stem}.{os.getpid()}-{threading.get_ident()}"
                                 f".partial{target.suffix}")
    try:
        yield temporary
        os.replace(temporary, target)
    except OSError as error:  # named as the path asked for, not the temporary
        if error.filename != str(temporary):
            raise
        raise type(error)(error.errno, error.strerror, str(path)) from None
    finally:
        temporary.unlink(missing_ok=True)


def write_or_return(path_or_file, write):
    """The one convention of every ``to_csv`` / ``to_json``: ``write(target)`` writes the
    output to a text file object or to a file name (NumPy's writers take either, and pick
    compression by the name's suffix). Without a destination, the text is returned; given a
    path, the file is written whole (``written``) and its ``Path`` returned; given an open
    text file, the output is written to it and the file returned."""
    if path_or_file is None:
        out = io.StringIO()
        write(out)
        return out.getvalue()
    if hasattr(path_or_file, "write"):
        write(path_or_file)
        return path_or_file
    path = output_file("path_or_file", path_or_file)
    with written(path) as temporary:
        write(temporary)
    return path


def text_writer(text: str):
    """``write_or_return``'s writer of a finished text: exactly these characters."""
    def write(target):
        if hasattr(target, "write"):
            target.write(text)
        else:
            pathlib.Path(target).write_text(text, encoding="utf-8", newline="")
    return write


def _special(path: pathlib.Path) -> bool:
    """Whether ``path`` exists and is neither a regular file nor a folder (a device, a pipe)."""
    return path.exists() and not path.is_file() and not path.is_dir()


def _target(path: pathlib.Path) -> pathlib.Path:
    """The file a write to ``path`` changes: a symbolic link's target."""
    return path.resolve() if path.is_symlink() else path
