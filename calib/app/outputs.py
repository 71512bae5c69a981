"""The output boundary for calib's commands and library users: :mod:`gyrosim.outputs`, re-exported.

Stable API: :func:`check_output_paths` (before any work: writable, not a folder, never an
input), :func:`write_json_atomic` (any dict; NaN/inf → ``null`` with the reason appended to its
``warnings``), :func:`write_text_atomic`, :func:`atomic_path` (temp file + rename for any writer),
:func:`staged_folder` (a report set, all or nothing), :func:`json_safe`.  It lives in gyrosim
because the simulator's command line needs it too, and gyrosim never imports calib.
"""

from gyrosim.outputs import (
                             atomic_path,
                             check_output_paths,
                             json_safe,
                             same_file,
                             staged_folder,
                             write_bytes_atomic,
                             write_json_atomic,
                             write_text_atomic,
)

__all__ = ["check_output_paths", "atomic_path", "write_text_atomic", "write_bytes_atomic", "write_json_atomic",
           "json_safe", "staged_folder", "same_file"]
