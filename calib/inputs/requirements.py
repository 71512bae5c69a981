"""What each method needs from a recording: one :class:`Requirements` per method, passed to the
boundary (:func:`calib.inputs.open_recording`), so the checks are the same code for every command
and only the limits differ.  A new command defines its own instance (e.g. ``calib mag``) and passes
it; nothing here switches on command names.

Limits and where they come from:

* ``KF`` (``calib run``, Zhou 2020 filter, both methods): 20 Hz – 1 kHz, measured on the zhou2020
  session (typical hand, consumer sensor, seed 1): every 5th sample (20 Hz) calibrates like 100 Hz
  (S within 2.2σ), every 10th (10 Hz, aliased hand tremor) diverges (S off by 0.9 %, 47σ); at
  the top the filter diverged at 3.3, 5 and 10 kHz but not at 2 or 2.5 kHz — the measurement noise
  R treats the hand's external acceleration as white per sample, so the information the filter
  takes from the accelerometer grows with the rate while the tremor it mistakes for attitude does
  not average out (root cause, see docs/bad-input.md).  1 kHz keeps a 2.5× margin; faster
  recordings are refused with ``--decimate``.  At least 10 s (2 s of rest + rotations).
* ``CLOSELOOP``: any rate up to 1 kHz (the truth reference keeps one row per sample; 10 kHz would
  need gigabytes of regressors), gaps allowed (it integrates over the actual Δt; they are listed).
* ``ALLAN``: a static record, ≥ 200 samples (fewer leave no τ range to fit).
* ``NOISE`` (``calib noise``): a static record of at least 64 samples (white noise alone needs
  J ≥ 3 octave scales with the largest Allan cluster ≤ T/8); each model asked needs more
  (:func:`calib.noise.minimum_samples`: 8·2^{p+1} for p parameters), checked by the command.
* ``MAG``: a hand session with a magnetometer; gaps listed, not refused (the field fits use samples,
  not their spacing); the magnetometer's own unit, range and coverage checks are
  :mod:`calib.mag.checks`'.
* ``INSPECT``: nothing is fatal but an unreadable file; problems are listed.
* ``GENERIC`` (``load_recording``'s default): reads and repairs, refuses only what cannot be read;
  each method's own :func:`~calib.inputs.check_recording` judges the rest.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

__all__ = [
    "Requirements",
    "KF",
    "CLOSELOOP",
    "ALLAN",
    "NOISE",
    "INSPECT",
    "TEMPERATURE",
    "RATETABLE",
    "MAG",
    "NORTHFIND",
    "TILT",
    "GENERIC",
]

HANDHELD_PLAUSIBLE_HZ = (0.5, 1e5)   # rates at which the seconds reading of a time column is believed
STATIC_PLAUSIBLE_HZ = (0.01, 1e5)    # static/chamber records may be logged slowly


@dataclass(frozen=True)
class Requirements:
    """Limits a method puts on its input (SI units in the names).

    Attributes
    ----------
        name: the command or method, for messages ("calib run").
        rate_hz: supported sample-rate range [lo, hi] after decimation; None: any.
        plausible_rate_hz: rates at which a time column is believed to be in seconds; outside it the
            time unit is looked for among ms, µs, ns (see :mod:`calib.inputs.timebase`).
        min_samples, min_duration_s: shortest usable record.
        max_bridged_gap_samples: gaps of up to this many missing samples are bridged by interpolation.
        gaps: "bridge" (larger gaps refused) or "allow" (larger gaps listed as warnings).
        motion: "any", "required" (refuse a motionless record) or "static" (refuse a moving one).
        strict: False: problems are collected in the report instead of raised (``calib inspect``).
        max_spike_fraction: at most this fraction of samples may be excluded as spikes.
        decimate_option: the command-line option that decimates (named in the rate message).
        why_max_rate: why the method cannot take faster data (for the message).
        sensors: the triads the method reads ("gyro", "acc"); a triad it does not read may be absent
            or constant (a tilt sensor's file carries zeros in the gyro columns) without a refusal.
    """

    name: str
    rate_hz: tuple[float, float] | None = None
    plausible_rate_hz: tuple[float, float] = HANDHELD_PLAUSIBLE_HZ
    min_samples: int = 2
    min_duration_s: float = 0.0
    max_bridged_gap_samples: int = 5
    gaps: str = "bridge"
    motion: str = "any"
    strict: bool = True
    max_spike_fraction: float = 0.01
    decimate_option: str = "--decimate"
    why_max_rate: str = ""
    sensors: tuple[str, ...] = ("gyro", "acc")

    def with_(self, **changes) -> "Requirements":
        """A copy with some limits changed (e.g. a closeloop minimum duration from --holdout)."""
        return replace(self, **changes)


# read + repair; each method checks (check_recording)
GENERIC = Requirements("calib.inputs.load_recording", strict=False)
KF = Requirements("calib run (Zhou 2020 filter)", rate_hz=(20.0, 1000.0), min_samples=200, min_duration_s=10.0,
                  motion="required",
                  why_max_rate="the filter treats the hand's external acceleration as white noise per sample, so at "
                               "high rates it trusts the accelerometer too much and diverges")
CLOSELOOP = Requirements("calib closeloop", rate_hz=(0.0, 1000.0), plausible_rate_hz=STATIC_PLAUSIBLE_HZ,
                         min_samples=50, gaps="allow",
                         why_max_rate="its truth and static references keep one residual row per sample: memory and "
                                      "time grow with the rate, the information does not")
ALLAN = Requirements("calib allan", plausible_rate_hz=STATIC_PLAUSIBLE_HZ, min_samples=200, motion="static")
NOISE = Requirements("calib noise", plausible_rate_hz=STATIC_PLAUSIBLE_HZ, min_samples=64, motion="static",
                     sensors=("gyro", "acc"))
INSPECT = Requirements("calib inspect", strict=False)
TEMPERATURE = Requirements("calib temperature", plausible_rate_hz=STATIC_PLAUSIBLE_HZ, min_samples=10, gaps="allow")
MAG = Requirements("calib mag", min_samples=50, gaps="allow")  # field fits do not integrate; the aided fit uses Δt
# north finding and the tilt test: holds at a few positions, turned by hand or a table in between (motion any)
NORTHFIND = Requirements("calib northfind", plausible_rate_hz=STATIC_PLAUSIBLE_HZ, min_samples=50, gaps="allow")
# the tilt test reads the accelerometer only: a tilt sensor has no gyro (its columns may be zeros)
TILT = Requirements("calib tilt", plausible_rate_hz=STATIC_PLAUSIBLE_HZ, min_samples=50, gaps="allow",
                    sensors=("acc",))
RATETABLE = Requirements("calib ratetable", plausible_rate_hz=STATIC_PLAUSIBLE_HZ, min_samples=10, gaps="allow")
