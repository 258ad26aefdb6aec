"""Atomic output files: write to a temporary sibling, then rename over the target.

An interrupted run therefore never leaves a half-written file under an output name.
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import os
import shutil
import tempfile
import tomllib
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path
from typing import IO, Any

from vtrack.errors import InputError


@contextlib.contextmanager
def atomic_open(path: str | os.PathLike, mode: str = "w", durable: bool = True,
                **kw: Any) -> Iterator[IO]:
    """Open a temporary file next to `path`; on success it replaces `path` atomically.

    durable=False skips the fsync (for many small files such as annotated frames, where
    atomicity matters but surviving a power cut does not)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)  # mkstemp's 0600 would make outputs private
    try:
        with os.fdopen(fd, mode, **kw) as fh:
            yield fh
            fh.flush()
            if durable:
                os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def write_text(path: str | os.PathLike, text: str) -> None:
    """Write a text file atomically."""
    with atomic_open(path, "w", encoding="utf-8") as fh:
        fh.write(text)


def write_json(path: str | os.PathLike, obj: Any) -> None:
    """Write pretty JSON atomically."""
    write_text(path, json.dumps(obj, indent=2) + "\n")


def write_csv(path: str | os.PathLike, rows: Iterable[Sequence[Any]],
              header: Sequence[str] | None = None) -> None:
    """Write a CSV file atomically (optional header row)."""
    with atomic_open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh, lineterminator="\n")
        if header is not None:
            w.writerow(header)
        w.writerows(rows)


def append_csv(path: str | os.PathLike, rows: Iterable[Sequence[Any]]) -> None:
    """Append CSV rows to an existing file in one write, then fsync: a growing output (made
    with `write_csv`, header first) is extended without being rewritten from the start."""
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerows(rows)
    text = buf.getvalue()
    if not text:
        return
    with open(path, "a", encoding="utf-8", newline="") as fh:
        fh.write(text)
        fh.flush()
        os.fsync(fh.fileno())


def replace_dir(path: str | os.PathLike) -> Path:
    """Empty (or create) an output sub-folder so no stale files from an earlier run stay."""
    path = Path(path)
    if path.exists():
        shutil.rmtree(path)
    path.mkdir(parents=True)
    return path


def open_input(path: str | os.PathLike, what: str, mode: str = "r", **kwargs: Any) -> IO:
    """Open a user's input file; a missing, unreadable or directory path is an InputError
    naming the file (`what` names the kind of file expected, e.g. "CSV file")."""
    try:
        return open(path, mode, **kwargs)
    except FileNotFoundError:
        raise InputError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise InputError(f"{path}: is a directory, not a {what}") from None
    except PermissionError:
        raise InputError(f"{path}: permission denied") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read: {exc.strerror or exc}") from None


def read_toml(path: str | os.PathLike) -> dict[str, Any]:
    """Parse a TOML file; any problem is an InputError naming the file."""
    try:
        with open_input(path, "TOML file", "rb") as fh:
            return tomllib.load(fh)
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: not UTF-8 text ({exc.reason})") from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: malformed TOML: {exc}") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read: {exc.strerror or exc}") from None


class GrowingFile:
    """An output file that grows without being rewritten from the start: a committed part,
    only ever appended to, followed by a provisional tail that each `write` replaces.

    The first `write` creates the file atomically (header included); each later one
    truncates it to the committed part and writes `final` (now committed) then `tail`, then
    fsyncs. Whoever reads it meanwhile (or after a crash) finds the committed part followed
    by the last write or a prefix of it: only a crash during that write itself can leave an
    incomplete last line. Data comes as chunks (iterables of bytes), so a large tail is
    never held whole in memory.
    """

    def __init__(self, path: str | os.PathLike, header: str = "") -> None:
        self.path = Path(path)
        self.header = header.encode()
        self.committed = 0        # bytes known final (header included)
        self.size = 0             # bytes in the file after the last write
        self._fh: IO[bytes] | None = None

    def write(self, final: Iterable[bytes] = (), tail: Iterable[bytes] = ()) -> None:
        """Append the chunks of `final` to the committed part; the chunks of `tail` replace
        the previous tail."""
        if self._fh is None:
            with atomic_open(self.path, "wb") as fh:
                fh.write(self.header)
                n_final, n_tail = _write_chunks(fh, final), _write_chunks(fh, tail)
            self._fh = open(self.path, "r+b")
            self.committed = len(self.header) + n_final
        else:
            self._fh.truncate(self.committed)
            self._fh.seek(self.committed)
            n_final, n_tail = _write_chunks(self._fh, final), _write_chunks(self._fh, tail)
            self._fh.flush()
            os.fsync(self._fh.fileno())
            self.committed += n_final
        self.size = self.committed + n_tail

    def close(self) -> None:
        if self._fh is not None:
            self._fh.close()
            self._fh = None


def _write_chunks(fh: IO[bytes], chunks: Iterable[bytes]) -> int:
    """Write every chunk; returns the number of bytes written."""
    return sum(fh.write(chunk) for chunk in chunks)
