"""Reading an HDF5 recording: the gyrosim layout (``/t``, ``/gyro``, ``/acc`` …, see
:mod:`gyrosim.recording`) or a BROAD trial as published (``imu_gyr``, ``imu_acc``, …).

Refusals name what is wrong with the file: truncated or corrupt (h5py cannot open or read it),
empty (no datasets), the datasets it has when the required ones are missing, a dataset that is a
group, text, complex or of the wrong shape.  Integer datasets are read as numbers (raw counts are
then named by :mod:`calib.inputs.degenerate`).
"""

from __future__ import annotations

from pathlib import Path

import h5py

from gyrosim.recording import Recording, load_hdf5

from calib.inputs.errors import FormatError, TooShortError

__all__ = ["read_hdf5"]


def _check_dataset(f: h5py.File, name: str, path: Path, ndim: int) -> None:
    obj = f[name]
    if not isinstance(obj, h5py.Dataset):
        raise FormatError(f"{path}: /{name} is a group, not a dataset: not a gyrosim recording")
    kind = obj.dtype.kind
    if kind not in "fiub":
        raise FormatError(f"{path}: /{name} holds {obj.dtype} values, not numbers")
    shape = obj.shape
    if len(shape) != ndim or (ndim == 2 and shape[1] != 3):
        want = "(N,)" if ndim == 1 else "(N, 3)"
        raise FormatError(f"{path}: /{name} has shape {shape}, expected {want}")


def read_hdf5(path: Path) -> tuple[Recording, list[str]]:
    """Read a gyrosim or BROAD HDF5 file (content already known to be HDF5); returns the recording
    and notes."""
    from gyrosim import loaders

    try:
        with h5py.File(path, "r") as f:
            names = sorted(f.keys())
            is_broad = "imu_gyr" in f and "t" not in f
            if not is_broad:
                if not names:
                    raise FormatError(f"{path} is an HDF5 file with no datasets: not a recording (a gyrosim recording "
                                      "has /t, /gyro, /acc)")
                missing = [k for k in ("t", "gyro", "acc") if k not in f]
                if missing:
                    raise FormatError(f"{path} lacks dataset(s) {['/' + m for m in missing]} (it has "
                                      f"{['/' + n for n in names[:10]]}): not a gyrosim recording nor a BROAD trial")
                _check_dataset(f, "t", path, 1)
                _check_dataset(f, "gyro", path, 2)
                _check_dataset(f, "acc", path, 2)
                n = {k: f[k].shape[0] for k in ("t", "gyro", "acc")}
                if len(set(n.values())) > 1:
                    raise FormatError(f"{path}: /t, /gyro, /acc have different lengths {n}: truncated or mismatched")
                if n["t"] < 2:
                    raise TooShortError(f"{path} holds {n['t']} sample(s): a recording needs at least 2")
                for opt, nd in (("temp", 1), ("mag", 2)):
                    if opt in f:
                        _check_dataset(f, opt, path, nd)
        if is_broad:
            return loaders.load_broad(path), ["BROAD trial (HDF5 as published)"]
        rec = load_hdf5(path)
    except FormatError:
        raise
    except (OSError, KeyError, ValueError, TypeError, RuntimeError) as exc:
        from gyrosim.errors import GyrosimError

        if isinstance(exc, GyrosimError):
            raise
        raise FormatError(f"{path} is an HDF5 file that cannot be read (truncated or corrupt?): {exc}; "
                          "re-export or re-copy it") from exc
    return rec, []
