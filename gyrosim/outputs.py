"""The output boundary: every path a command writes is checked before the work starts, and every
file is written atomically, so nothing the user gave is overwritten and nothing is left half-written.

Used by both command lines (``gyrosim`` and ``calib``; calib re-exports it as :mod:`calib.app.outputs`).
A stable, generic API (any command, any dict):

* :func:`check_output_paths` — before any computation: each output's folder exists and is
  writable, a file output is not a directory (and a folder output is not a file), no two outputs
  are the same path, and **no output equals an input** (compared after resolving symlinks and
  ``..``; hard links too, via :func:`os.path.samefile`).  Raises :class:`OutputPathError` naming the
  path and what to do.
* :func:`atomic_path` — a context manager yielding a temporary path in the target's folder; on
  success it is renamed over the target (``os.replace``: atomic on POSIX and Windows within one
  file system), on any exception it is deleted.  :func:`write_text_atomic`,
  :func:`write_bytes_atomic`, :func:`write_json_atomic` build on it.
* :func:`staged_folder` — a report *set* (several files in one folder) written all-or-nothing:
  files go to a hidden staging folder beside the target and are moved in only when all are done.
* :func:`json_safe` / :func:`write_json_atomic` — JSON has no NaN or infinity (``json.dumps``
  would write the invalid bare tokens ``NaN``/``Infinity``): every non-finite float becomes
  ``null`` and its location is listed in the document's ``warnings`` with the reason given by the
  caller (or "not computable").
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any, Iterable, Iterator, Mapping

from .errors import OutputPathError

__all__ = ["check_output_paths", "atomic_path", "write_text_atomic", "write_bytes_atomic", "write_json_atomic",
           "json_safe", "staged_folder", "same_file"]

PathLike = str | os.PathLike[str]


def _resolved(p: PathLike) -> Path:
    return Path(os.path.abspath(os.path.expanduser(os.fspath(p)))).resolve()


def same_file(a: PathLike, b: PathLike) -> bool:
    """True when ``a`` and ``b`` name the same file: equal after resolving, or the same inode."""
    ra, rb = _resolved(a), _resolved(b)
    if ra == rb:
        return True
    try:
        return os.path.samefile(ra, rb)
    except OSError:
        return False


def _writable_folder(folder: Path, what: str, path: PathLike) -> None:
    if not folder.exists():
        raise OutputPathError(f"cannot write {what} {os.fspath(path)!r}: folder {str(folder)!r} does not exist; create "
                              "it first")
    if not folder.is_dir():
        raise OutputPathError(f"cannot write {what} {os.fspath(path)!r}: {str(folder)!r} is not a folder")
    try:
        fd, probe = tempfile.mkstemp(prefix=".write-probe.", dir=folder)
    except OSError as exc:
        raise OutputPathError(f"cannot write {what} {os.fspath(path)!r}: folder {str(folder)!r} is not writable "
                              f"({exc.strerror}); choose another folder") from exc
    os.close(fd)
    os.unlink(probe)


def check_output_paths(outputs: Mapping[str, PathLike | None], inputs: Iterable[PathLike | None] = (), *,
                       folders: Iterable[str] = (), folder_files: Mapping[str, Iterable[str]] | None = None) -> None:
    """Check every output before the work starts; raise :class:`OutputPathError` on the first problem.

    Args:
        outputs: option name (for the message, e.g. ``"--json"``) → path; ``None`` entries (option
            not given) are skipped.
        inputs: every file the command reads (recordings, TOML files, ...); ``None`` and names that
            are not existing paths (e.g. a preset name) are skipped.
        folders: option names in ``outputs`` that are output *folders* (created if missing, one
            level: the parent must exist) rather than files.
        folder_files: for a folder output, the file names the command writes into it: each must
            not be an input either (``closeloop --out`` on the folder that holds the recording as
            ``report.json``...).
    """
    folders = set(folders)
    real_inputs = [Path(os.fspath(p)) for p in inputs if p is not None and Path(os.fspath(p)).exists()]
    seen: dict[Path, str] = {}
    for opt, out in outputs.items():
        if out is None:
            continue
        if not os.fspath(out).strip():
            raise OutputPathError(f"{opt}: empty path; give a file name")
        path = Path(os.fspath(out))
        res = _resolved(path)
        if res in seen:
            raise OutputPathError(
                f"{opt} and {seen[res]} name the same path {os.fspath(out)!r}; give each its own file"
            )
        seen[res] = opt
        targets = [path]
        if opt in folders:
            if path.exists() and not path.is_dir():
                raise OutputPathError(f"{opt} {os.fspath(out)!r} is a file, but this option names an output folder; "
                                      "give a folder path")
            for inp in real_inputs:
                if same_file(inp, path):
                    raise OutputPathError(
                        f"{opt} {os.fspath(out)!r} is the input itself; give a separate output folder"
                    )
            targets = [path / name for name in (folder_files or {}).get(opt, ())]
            _writable_folder(path if path.is_dir() else (res.parent), "folder", out)
        else:
            if path.is_dir():
                raise OutputPathError(f"{opt} {os.fspath(out)!r} is a folder; give a file name (e.g. {path / 'out'})")
            _writable_folder(res.parent, "file", out)
        for t in targets:
            for inp in real_inputs:
                if same_file(inp, t):
                    raise OutputPathError(
                        f"{opt} {os.fspath(out)!r} would overwrite the input {os.fspath(inp)!r}: inputs are never "
                        "overwritten; choose another output path")


@contextlib.contextmanager
def atomic_path(path: PathLike) -> Iterator[Path]:
    """Yield a temporary path beside ``path`` (same suffix, so writers that infer the format from
    it work); rename it onto ``path`` when the block succeeds, delete it when it fails."""
    path = Path(os.fspath(path))
    folder = path.parent if str(path.parent) else Path(".")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=f".part{path.suffix}", dir=folder)
    os.close(fd)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; an output gets the user's usual mode
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_bytes_atomic(path: PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (see :func:`atomic_path`) and return the path."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return Path(os.fspath(path))


def write_text_atomic(path: PathLike, text: str) -> Path:
    """Write UTF-8 text atomically (see :func:`atomic_path`)."""
    return write_bytes_atomic(path, text.encode("utf-8"))


def _key_path(prefix: str, key: Any) -> str:
    return f"{prefix}.{key}" if prefix else str(key)


def json_safe(obj: Any, reasons: Mapping[str, str] | None = None) -> tuple[Any, list[str]]:
    """A copy of ``obj`` that ``json.dumps`` writes as valid JSON, and the notes on what was nulled.

    numpy scalars and arrays become Python numbers and lists, tuples lists, dict keys strings;
    NaN and ±inf become ``None``.  Each nulled location is reported once per array/field as
    ``"<path>: <reason> → null"``; ``reasons`` maps a location prefix (``"gyro.std"``) to the reason
    (default ``"not computable (NaN)"`` / ``"infinite"``)."""
    reasons = dict(reasons or {})
    notes: dict[str, str] = {}

    def reason(path: str, value: float) -> str:
        best = max((k for k in reasons if path == k or path.startswith(k + ".") or path.startswith(k + "[")),
                   key=len, default=None)
        if best is not None:
            return reasons[best]
        return "not computable (NaN)" if math.isnan(value) else "infinite"

    def walk(o: Any, path: str, field: str) -> Any:
        if isinstance(o, Mapping):
            return {str(k): walk(v, _key_path(path, k), _key_path(path, k)) for k, v in o.items()}
        if hasattr(o, "tolist") and not isinstance(o, (str, bytes)):  # numpy array or scalar
            return walk(o.tolist(), path, field)
        if isinstance(o, (list, tuple)):
            return [walk(v, f"{path}[{i}]", field) for i, v in enumerate(o)]
        if isinstance(o, bool) or o is None or isinstance(o, (int, str)):
            return o
        if isinstance(o, float):
            if math.isfinite(o):
                return o
            notes.setdefault(field, reason(path, o))
            return None
        if isinstance(o, os.PathLike):
            return os.fspath(o)
        raise TypeError(f"{path or 'value'}: {type(o).__name__} is not JSON-serialisable")

    out = walk(obj, "", "")
    return out, [f"{k or 'value'}: {v} → null" for k, v in notes.items()]


def write_json_atomic(
    path: PathLike, obj: Any, *, reasons: Mapping[str, str] | None = None, indent: int = 2
) -> list[str]:
    """Write ``obj`` as valid JSON, atomically; return the notes on nulled values.

    NaN/inf become ``null`` (:func:`json_safe`); when ``obj`` is a dict, the notes are appended to
    its ``warnings`` list (created if absent) in the file, so a reader learns why a number is
    missing.  The caller's object is not modified."""
    data, notes = json_safe(obj, reasons)
    if notes and isinstance(data, dict):
        w = data.get("warnings")
        data["warnings"] = (list(w) if isinstance(w, list) else ([] if w is None else [w])) + notes
    write_text_atomic(path, json.dumps(data, indent=indent, ensure_ascii=False, allow_nan=False) + "\n")
    return notes


@contextlib.contextmanager
def staged_folder(out: PathLike) -> Iterator[Path]:
    """Yield a staging folder for a set of files that belong in ``out``; on success move them in.

    The staging folder is a hidden sibling of ``out`` (same file system, so the moves are renames).
    If ``out`` does not exist the whole staging folder is renamed to it (one atomic step); if it
    exists, each staged file replaces its namesake in turn (each replacement atomic).  On any
    exception the staging folder is removed and ``out`` is left as it was."""
    out = Path(os.fspath(out))
    parent = out.parent if str(out.parent) else Path(".")
    stage = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".part", dir=parent))
    try:
        yield stage
        if not out.exists():
            os.chmod(stage, 0o777 & ~_umask())
            os.replace(stage, out)
            return
        for f in sorted(stage.rglob("*")):
            if f.is_file():
                target = out / f.relative_to(stage)
                target.parent.mkdir(parents=True, exist_ok=True)
                os.replace(f, target)
    finally:
        if stage.exists():
            shutil.rmtree(stage, ignore_errors=True)


def _umask() -> int:
    u = os.umask(0)
    os.umask(u)
    return u
