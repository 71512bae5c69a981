"""``calib inspect``: what a recording holds and what the input boundary made of it, as a typed result.

:func:`summarise_recording` takes what :func:`calib.inputs.load_checked`-style loading returns (the
recording and its :class:`~calib.inputs.InputReport`) and gives a :class:`RecordingSummary`;
``lines()`` is the text ``calib inspect`` prints.  Units: s, Hz, rad/s, m/s².
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gyrosim.recording import Recording

__all__ = ["RecordingSummary", "summarise_recording"]

META_KEYS = ("schedule", "hand", "sensor", "seed", "source", "version")


@dataclass(frozen=True)
class RecordingSummary:
    """Length, rate and channels of a recording, its provenance (metadata) and the input report."""

    name: str
    samples: int
    duration_s: float
    rate_hz: float
    dt_min_s: float
    dt_max_s: float
    gyro_norm_max_rad_s: float
    acc_norm_mean_m_s2: float
    has_temperature: bool
    has_magnetometer: bool
    truth_channels: tuple[str, ...] | None   # None: no truth at all
    provenance: tuple[tuple[str, str], ...]
    report: object  # calib.inputs.InputReport

    def lines(self) -> list[str]:
        """The summary as ``calib inspect`` prints it (input warnings are printed by the CLI's helper)."""
        rep = self.report
        out = [f"{self.name}: {self.samples} samples, {self.duration_s:.2f} s, rate {self.rate_hz:g} Hz "
               f"(Δt {self.dt_min_s * 1e3:.3f}–{self.dt_max_s * 1e3:.3f} ms)",
               f"  gyro |ω| max {self.gyro_norm_max_rad_s:.3f} rad/s, acc |f| mean {self.acc_norm_mean_m_s2:.4f} m/s²",
               f"  temperature: {'yes' if self.has_temperature else 'no'}, "
               f"magnetometer: {'yes' if self.has_magnetometer else 'no'}, "
               f"truth: {', '.join(self.truth_channels) if self.truth_channels is not None else 'none'}"]
        out += [f"  {k}: {v}" for k, v in self.provenance]
        out.append(f"  format: {rep.format}" + (f", {rep.encoding}" if rep.encoding else "")
                   + (f", separator {rep.separator}" if rep.separator else "")
                   + f"; time unit {rep.time_unit} ({rep.time_unit_how})")
        if rep.ignored_columns:
            out.append(f"  ignored columns: {', '.join(rep.ignored_columns)}")
        out.append(f"  saturated samples: {rep.saturated_samples}")
        return out


def summarise_recording(name: str, rec: Recording, report) -> RecordingSummary:
    """The :class:`RecordingSummary` of ``rec`` as loaded (``report``: the input boundary's report)."""
    dt = np.diff(rec.t_s)
    prov = []
    for key in META_KEYS:
        if key in rec.meta:
            v = rec.meta[key]
            prov.append((key, str(v["name"] if isinstance(v, dict) and "name" in v else v)))
    return RecordingSummary(
        name,
        rec.n,
        rec.duration_s,
        rec.rate_hz,
        float(dt.min()),
        float(dt.max()),
        float(np.linalg.norm(rec.gyro_rad_s, axis=1).max()),
        float(np.linalg.norm(rec.acc_m_s2, axis=1).mean()),
        rec.temp_c is not None,
        rec.mag_ut is not None,
        tuple(rec.truth.channels()) if rec.truth else None,
        tuple(prov),
        report,
    )
