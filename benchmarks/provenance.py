"""The provenance stamp every results file carries: which code wrote it, with which command, when.

A stamp is a small dict::

    {"commit": "<git rev-parse HEAD>", "dirty": false, "command": "python benchmarks/x.py --out …",
     "date": "2026-12-01T10:00:00+00:00", ...}

``dirty`` is true when the checkout had changes outside ``docs/`` and ``README.md`` while the command ran
(``dirty_files`` lists them): those hold the guides and the results themselves, which no computation reads.  A
file written before results were stamped carries ``"commit": null`` and a ``note`` saying how to regenerate it.

Where the stamp goes, per file type (``stamp`` writes it, ``read`` finds it):

* JSON: the top-level key ``"provenance"`` (a top-level list becomes ``{"provenance": …, "rows": [...]}``);
* Markdown: a first-line comment ``<!-- provenance: {json} -->``;
* CSV: a first-line comment ``# provenance: {json}`` (``csv`` readers skip it with ``comment="#"``);
* PNG: a ``tEXt`` chunk with the keyword ``provenance``.
"""

from __future__ import annotations

import datetime as _dt
import json
import shlex
import subprocess
import sys
import zlib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MD_PREFIX = "<!-- provenance: "
CSV_PREFIX = "# provenance: "
PNG_KEY = b"provenance"
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def git_state(root: Path = ROOT) -> dict:
    """The checkout's commit and whether it has changes outside docs/ (``commit`` is None outside a git tree)."""
    try:
        commit = subprocess.run(["git", "rev-parse", "HEAD"], cwd=root, capture_output=True, text=True,
                                check=True).stdout.strip()
        status = subprocess.run(["git", "status", "--porcelain"], cwd=root,
                                capture_output=True, text=True, check=True).stdout.splitlines()
    except (OSError, subprocess.CalledProcessError):
        return {"commit": None, "dirty": None}
    changed = sorted({path for line in status if (path := line[3:].split(" -> ")[-1])
                      and not path.startswith("docs/") and path != "README.md"})
    state = {"commit": commit, "dirty": bool(changed)}
    if changed:
        state["dirty_files"] = changed[:20]
    return state


def command_line(argv: list[str] | None = None) -> str:
    """The command as a person would type it: ``python`` for the interpreter, paths relative to the checkout."""
    argv = list(sys.argv if argv is None else argv)
    if argv and Path(argv[0]).suffix == ".py":
        argv = ["python", _relative(argv[0]), *argv[1:]]
    return shlex.join(_relative(a) for a in argv)


def _relative(arg: str) -> str:
    p = Path(arg)
    if p.is_absolute():
        try:
            return str(p.resolve().relative_to(ROOT))
        except ValueError:
            return arg
    return arg


def stamp_for(command: str, **extra) -> dict:
    """A fresh stamp for ``command`` run now on this checkout (``extra`` keys are added as they are)."""
    return {**git_state(), "command": command,
            "date": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"), **extra}


def legacy_stamp(command: str, path: Path | None = None, note: str | None = None) -> dict:
    """The honest stamp of a file written before results were stamped: no commit, the command to regenerate it
    (and the commit that last changed the file in git, when there is one, as ``last_committed_in``)."""
    stamp = {"commit": None,
             "note": note or f"written before results were stamped; regenerate with {command}",
             "command": command}
    if path is not None:
        out = subprocess.run(["git", "log", "-1", "--format=%H", "--", str(path)], cwd=ROOT, capture_output=True,
                             text=True).stdout.strip()
        if out:
            stamp["last_committed_in"] = out
    return stamp


# ---------------------------------------------------------------------------------------------- writing
def write_json(path: str | Path, payload, command: str | None = None, **extra) -> dict:
    """Write ``payload`` as JSON with its provenance (the running command unless ``command`` is given)."""
    prov = stamp_for(command or command_line(), **extra)
    _write_text(Path(path), _json_text(_with_json_stamp(payload, prov)))
    return prov


def write_markdown(path: str | Path, text: str, command: str | None = None, **extra) -> dict:
    """Write Markdown ``text`` behind its provenance comment."""
    prov = stamp_for(command or command_line(), **extra)
    _write_text(Path(path), _md_stamp_line(prov) + _strip_md_stamp(text))
    return prov


def stamp(path: str | Path, prov: dict) -> None:
    """Put ``prov`` into an existing results file (replacing a stamp it already has)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".json":
        _write_text(path, _json_text(_with_json_stamp(json.loads(path.read_text(encoding="utf-8")), prov)))
    elif suffix == ".md":
        _write_text(path, _md_stamp_line(prov) + _strip_md_stamp(path.read_text(encoding="utf-8")))
    elif suffix == ".csv":
        lines = path.read_text(encoding="utf-8").splitlines(keepends=True)
        if lines and lines[0].startswith(CSV_PREFIX):
            lines = lines[1:]
        _write_text(path, CSV_PREFIX + json.dumps(prov, ensure_ascii=False) + "\n" + "".join(lines))
    elif suffix == ".png":
        path.write_bytes(_png_with_text(path.read_bytes(), PNG_KEY, json.dumps(prov).encode("latin-1", "replace")))
    else:
        raise ValueError(f"{path.name}: no provenance convention for {suffix or 'files without a suffix'}")


# ---------------------------------------------------------------------------------------------- reading
def read(path: str | Path) -> dict | None:
    """The provenance stamp of a results file, or None when it has none."""
    path = Path(path)
    suffix = path.suffix.lower()
    try:
        if suffix == ".json":
            data = json.loads(path.read_text(encoding="utf-8"))
            return data.get("provenance") if isinstance(data, dict) else None
        if suffix in (".md", ".csv"):
            first = path.read_text(encoding="utf-8").split("\n", 1)[0]
            if suffix == ".md" and first.startswith(MD_PREFIX) and first.rstrip().endswith("-->"):
                return json.loads(first[len(MD_PREFIX):first.rstrip().rindex("-->")])
            if suffix == ".csv" and first.startswith(CSV_PREFIX):
                return json.loads(first[len(CSV_PREFIX):])
            return None
        if suffix == ".png":
            text = _png_texts(path.read_bytes()).get(PNG_KEY)
            return json.loads(text.decode("latin-1")) if text is not None else None
    except (ValueError, OSError):
        return None
    return None


def body(path: str | Path) -> str:
    """A Markdown results file without its provenance line."""
    return _strip_md_stamp(Path(path).read_text(encoding="utf-8"))


def short(prov: dict | None) -> str:
    """One line for a person: ``abc1234 (dirty) 2026-12-01``, ``before stamping`` or ``not stamped``."""
    if not prov:
        return "not stamped"
    if not prov.get("commit"):
        return "before stamping"
    return f"{prov['commit'][:7]}{' (dirty)' if prov.get('dirty') else ''} {str(prov.get('date', ''))[:10]}".strip()


# ---------------------------------------------------------------------------------------------- helpers
def _with_json_stamp(payload, prov: dict) -> dict:
    if isinstance(payload, list):
        payload = {"rows": payload}
    if not isinstance(payload, dict):
        raise TypeError("a results JSON is an object or a list")
    return {"provenance": prov, **{k: v for k, v in payload.items() if k != "provenance"}}


def _json_text(data) -> str:
    return json.dumps(data, indent=1, ensure_ascii=False, default=_default) + "\n"


def _default(o):
    try:
        return o.tolist()
    except AttributeError:
        return float(o)


def _md_stamp_line(prov: dict) -> str:
    return MD_PREFIX + json.dumps(prov, ensure_ascii=False) + " -->\n"


def _strip_md_stamp(text: str) -> str:
    first, _, rest = text.partition("\n")
    return rest if first.startswith(MD_PREFIX) else text


def _write_text(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text, encoding="utf-8")
    tmp.replace(path)


def _png_chunks(data: bytes):
    if not data.startswith(PNG_SIGNATURE):
        raise ValueError("not a PNG file")
    i = len(PNG_SIGNATURE)
    while i < len(data):
        n = int.from_bytes(data[i:i + 4], "big")
        kind = data[i + 4:i + 8]
        yield kind, data[i:i + 12 + n], data[i + 8:i + 8 + n]
        i += 12 + n


def _png_texts(data: bytes) -> dict[bytes, bytes]:
    return {payload.split(b"\0", 1)[0]: payload.split(b"\0", 1)[1]
            for kind, _, payload in _png_chunks(data) if kind == b"tEXt" and b"\0" in payload}


def _png_with_text(data: bytes, key: bytes, text: bytes) -> bytes:
    """The PNG with one tEXt chunk ``key`` (any former one removed), placed right after IHDR."""
    payload = key + b"\0" + text
    chunk = len(payload).to_bytes(4, "big") + b"tEXt" + payload + zlib.crc32(b"tEXt" + payload).to_bytes(4, "big")
    out = [PNG_SIGNATURE]
    for kind, raw, body_ in _png_chunks(data):
        if kind == b"tEXt" and body_.split(b"\0", 1)[0] == key:
            continue
        out.append(raw)
        if kind == b"IHDR":
            out.append(chunk)
    return b"".join(out)
