r"""What a file is, from its content (never from its name): HDF5 or text, and for text the encoding
(UTF-8, with or without a byte-order mark; UTF-16 with one) and the field separator.

* ROS bags: ``#ROSBAG V2.0`` (ROS 1), the MCAP magic ``\x89MCAP0\r\n`` or an SQLite database (a ROS 2
  bag's storage file, ``.db3``): kind ``"rosbag"``, read by :mod:`calib.inputs.rosbag`.
* HDF5: the 8-byte signature ``\x89HDF\r\n\x1a\n`` at offset 0, 512, 1024, 2048, … (a user block
  may precede it; HDF5 spec §II.A).
* Text: decodes as UTF-8 (a leading BOM is removed and named), or as UTF-16 when it starts with a
  UTF-16 BOM, or as Latin-1 when it is printable in it (old Windows exports with "°"); anything
  else — NUL bytes, control characters, undecodable bytes — is binary and refused.
* Separator: of ``,`` ``;`` tab ``|`` (and runs of spaces), the one that splits the header line into
  the most fields, checked against the first data line.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from calib.inputs.errors import FormatError

__all__ = ["Sniffed", "sniff", "detect_separator", "HDF5_SIGNATURE", "ROSBAG_SIGNATURES", "SEPARATOR_NAMES"]

HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
ROSBAG_SIGNATURES = {b"#ROSBAG V2.0": "ROS 1 bag", b"\x89MCAP0\r\n": "MCAP (ROS 2 bag)",
                     b"SQLite format 3\x00": "SQLite (ROS 2 bag)"}
SEPARATOR_NAMES = {",": "comma ','", ";": "semicolon ';'", "\t": "tab", "|": "vertical bar '|'", " ": "spaces"}
_MAX_TEXT_BYTES = 2_000_000_000


@dataclass(frozen=True)
class Sniffed:
    """``kind``: "hdf5", "rosbag" or "text"; ``text`` (decoded, BOM removed) and ``encoding`` for text
    (for "rosbag": which storage)."""

    kind: str
    encoding: str | None = None
    text: str | None = None
    notes: tuple[str, ...] = ()


def _hdf5_signature_at(head: bytes, size: int, path: Path) -> bool:
    if head.startswith(HDF5_SIGNATURE):
        return True
    off = 512
    with path.open("rb") as fh:
        while off + 8 <= size and off <= 1 << 20:
            fh.seek(off)
            if fh.read(8) == HDF5_SIGNATURE:
                return True
            off *= 2
    return False


def _looks_binary(text: str) -> bool:
    """Control characters other than tab/CR/LF/FF, or U+FFFD, in more than 0.1 % of the characters."""
    sample = text[:65536]
    if not sample:
        return False
    bad = sum(1 for c in sample if (ord(c) < 32 and c not in "\t\r\n\f") or c == "\ufffd" or 0x7F <= ord(c) < 0xA0)
    return bad > max(0, len(sample) // 1000)


def _describe(data: bytes) -> str:
    return " ".join(f"{b:02x}" for b in data[:8])


def sniff(path: Path) -> Sniffed:
    """Classify ``path`` by content; raises :class:`FormatError` for empty or binary files."""
    size = path.stat().st_size
    if size == 0:
        raise FormatError(f"{path} is empty (0 bytes): not a recording")
    with path.open("rb") as fh:
        head = fh.read(4096)
    if _hdf5_signature_at(head, size, path):
        return Sniffed("hdf5")
    for magic, what in ROSBAG_SIGNATURES.items():
        if head.startswith(magic):
            return Sniffed("rosbag", what)
    if size > _MAX_TEXT_BYTES:
        raise FormatError(f"{path} is {size / 1e9:.1f} GB of text: too large to read as CSV; convert it to HDF5")
    data = path.read_bytes()
    notes: list[str] = []
    if data.startswith(b"\xef\xbb\xbf"):
        text, enc = data[3:].decode("utf-8", errors="replace"), "utf-8 with BOM"
        notes.append("the file starts with a UTF-8 byte-order mark (removed)")
    elif data.startswith((b"\xff\xfe", b"\xfe\xff")):
        try:
            text, enc = data.decode("utf-16"), "utf-16"
        except UnicodeDecodeError as exc:
            raise FormatError(f"{path} starts with a UTF-16 byte-order mark but does not decode as UTF-16 "
                              f"({exc.reason})") from exc
        notes.append("the file is UTF-16 text (read as such)")
    else:
        try:
            text, enc = data.decode("utf-8"), "utf-8"
        except UnicodeDecodeError:
            text, enc = data.decode("latin-1"), "latin-1"
            if _looks_binary(text):
                raise FormatError(
                    f"{path} is neither HDF5 (no HDF5 signature) nor text (its first bytes are {_describe(data)}): "
                    "not a recording; give a gyrosim HDF5 or a CSV with a header "
                    "t,gyro_x,gyro_y,gyro_z,acc_x,acc_y,acc_z"
                ) from None
            notes.append("the file is not UTF-8; read as Latin-1")
    if "\x00" in text[:65536] or _looks_binary(text):
        raise FormatError(
            f"{path} is binary ({'NUL bytes' if chr(0) in text[:65536] else 'control characters'}; first bytes "
            f"{_describe(data)}), neither HDF5 nor CSV text: not a recording"
        )
    if path.suffix.lower() in (".h5", ".hdf5", ".hdf"):
        notes.append(f"the file is named {path.suffix} but holds text: read as CSV")
    return Sniffed("text", enc, text, tuple(notes))


def detect_separator(header: str, first_data: str | None) -> str:
    """The separator among , ; tab | spaces that splits ``header`` into the most fields (and the
    first data line into as many, when given); ',' when nothing splits."""
    best, best_n = ",", 1
    for sep in (",", ";", "\t", "|"):
        n = len(header.split(sep))
        if n > best_n and (first_data is None or len(first_data.split(sep)) == n):
            best, best_n = sep, n
    if best_n == 1:
        fields = re.split(r"\s+", header.strip())
        if len(fields) > 1 and (first_data is None or len(re.split(r"\s+", first_data.strip())) == len(fields)):
            return " "
    if best_n == 1:  # counts differ between header and data: fall back to the header alone
        for sep in (",", ";", "\t", "|"):
            n = len(header.split(sep))
            if n > best_n:
                best, best_n = sep, n
    return best
