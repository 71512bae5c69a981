"""What the hand cost this session ("Coach the user"): ``calib run``'s report.

Three findings, all from the recording itself (a user's file; nothing from a simulator):

* **external acceleration seen** (m/s² RMS, magnitude of the 3-vector): |f| − g is the component of
  the hand's acceleration a_e along gravity; for an isotropic a_e, E[(|f| − g)²] = |a_e|²/3, so
  |a_e|_RMS ≈ √(3 (⟨(|f| − g)²⟩ − σ_f²)) — split at ``calib.session.hand.lowpass.CUTOFF_HZ`` into the tremor band
  (removed by a low-pass) and the slow part (sway, the lever arm's ω²r: what costs accuracy);
* **σ reached vs σ an ideal hand would reach**: the result's σ of S and G beside the Cramér–Rao bound
  of the same rotations with the sensor's white noise only (the Riccati recursion of the paper's
  9-state model, :func:`calib.session.kernel.run_filter`, on the session's own attitude: the gyro integrated
  from the rest attitude, gravity predicted from it, so the residual is zero and P is the information
  of that trajectory), noise densities from the spectrum above the tremor band
  (:func:`calib.session.noiselevels.white_density`).  The ratio is what the hand cost;
* **segments that hurt most**: 10-s stretches of motion (outside the detected rests), ranked by their
  slow external acceleration (RMS of the low-passed |f| − g, ×√3), with their times — the ones to redo
  more smoothly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from gyrosim.calibration import Calibration
from gyrosim.recording import Recording
from gyrosim.rotations import quat_conjugate, quat_rotate
from gyrosim.strapdown import integrate_gyro

from calib.session.hand.lowpass import lowpass
from calib.session.kernel import run_filter
from calib.session.model import PAPER, initial_covariance, m_matrix
from calib.session.prepare import Prepared, rest_mask

__all__ = ["Coaching", "coach"]

SEGMENT_S = 10.0
SG = ("S_x", "S_y", "S_z", "G_x", "G_y", "G_z")


@dataclass(frozen=True)
class Coaching:
    """The findings of the module docstring (SI; σ of S and G dimensionless)."""

    external_acc_rms_m_s2: float
    tremor_band_rms_m_s2: float
    slow_rms_m_s2: float
    sigma_reached: np.ndarray
    sigma_ideal_hand: np.ndarray
    worst_segments: tuple[dict, ...]

    @property
    def cost(self) -> np.ndarray:
        return self.sigma_reached / self.sigma_ideal_hand

    @classmethod
    def from_dict(cls, d: dict) -> "Coaching":
        """Inverse of :meth:`to_dict` (``calib run --json``'s ``coaching``)."""
        return cls(d["external_acc_rms_m_s2"], d["tremor_band_rms_m_s2"], d["slow_external_acc_rms_m_s2"],
                   np.array([d["sigma_reached"][k] for k in SG], float),
                   np.array([d["sigma_ideal_hand"][k] for k in SG], float), tuple(d["worst_segments"]))

    def to_dict(self) -> dict:
        return {"external_acc_rms_m_s2": self.external_acc_rms_m_s2, "tremor_band_rms_m_s2": self.tremor_band_rms_m_s2,
                "slow_external_acc_rms_m_s2": self.slow_rms_m_s2,
                "sigma_reached": dict(zip(SG, self.sigma_reached.tolist())),
                "sigma_ideal_hand": dict(zip(SG, self.sigma_ideal_hand.tolist())),
                "sigma_over_ideal": dict(zip(SG, self.cost.tolist())), "worst_segments": list(self.worst_segments)}

    def lines(self) -> list[str]:
        c = self.cost
        out = [
            f"the hand: external acceleration {self.external_acc_rms_m_s2:.3f} m/s² RMS "
            f"(tremor band {self.tremor_band_rms_m_s2:.3f}, slow {self.slow_rms_m_s2:.3f})",
            "σ of S, G reached "
            f"{np.array2string(self.sigma_reached, precision=1, formatter={'float': '{:.1e}'.format})}"
            f" vs an ideal hand's {np.array2string(self.sigma_ideal_hand, formatter={'float': '{:.1e}'.format})}: "
            f"×{float(np.median(c)):.1f} (median; worst ×{float(np.max(c)):.1f} on {SG[int(np.argmax(c))]})",
        ]
        if self.worst_segments:
            out.append("segments that hurt most (slow external acceleration): " + "; ".join(
                f"{s['t_s'][0]:.0f}–{s['t_s'][1]:.0f} s ({s['slow_external_acc_rms_m_s2']:.3f} m/s²)"
                for s in self.worst_segments))
        return out


def _acc_rms(excess: np.ndarray, sigma2: float) -> float:
    return math.sqrt(max(3.0 * (float(np.mean(excess**2)) - sigma2), 0.0))


def coach(rec: Recording, cal: Calibration, prep: Prepared, top: int = 3) -> Coaching:
    """The findings of the module docstring for ``cal`` (a calibration of ``rec``; ``prep`` its
    :func:`calib.session.prepare.prepare`)."""
    fs, a = rec.rate_hz, prep.start
    cfg = prep.config
    arw = prep.noise.gyro_density_rad_s_sqrt_hz or cfg.arw_rad_s_sqrt_hz     # the rest's spectrum (prepare's)
    vrw = prep.noise.acc_density_m_s2_sqrt_hz or cfg.vrw_m_s2_sqrt_hz
    g = cfg.gravity_m_s2
    f = rec.acc_m_s2
    if cal.has("accelerometer", "bias"):   # the calibration's own accelerometer, so |f̂| − g is the hand's
        m = m_matrix(cal.value("accelerometer", "scale_factor"), cal.value("accelerometer", "nonorthogonality"))
        f = (f - cal.value("accelerometer", "bias")) @ np.linalg.inv(m).T
    excess = np.linalg.norm(f[a:], axis=1) - g
    lp = lowpass(excess, fs)
    s2 = vrw**2 * fs
    total = _acc_rms(excess, s2)
    slow = _acc_rms(lp, 0.0)
    tremor = math.sqrt(max(total**2 - slow**2, 0.0))
    # the ideal hand's bound on this session's rotations
    m = m_matrix(cal.scale_factor, cal.nonorthogonality)
    w = (rec.gyro_rad_s[a:] - cal.bias_rad_s) @ np.linalg.inv(m).T
    t = rec.t_s[a:]
    q = integrate_gyro(t, w, prep.quat0_nb)
    f_g = quat_rotate(quat_conjugate(q), np.array([0.0, 0.0, g]))
    ideal = replace(cfg, arw_rad_s_sqrt_hz=arw, vrw_m_s2_sqrt_hz=vrw, external_acc_allowance_m_s2=0.0)
    theta = np.zeros(18)
    run = run_filter(w[None], f_g[None], t, prep.quat0_nb[None], theta[None], initial_covariance(PAPER, ideal), PAPER,
                     ideal, fs, rest_mask=rest_mask(prep, t.size))
    sig_ideal = np.sqrt(np.diag(run.p[0])[3:9])
    sig = np.sqrt(np.diag(cal.block_covariance([("gyro", "scale_factor"), ("gyro", "nonorthogonality")])))
    # stretches of SEGMENT_S seconds of motion (outside the detected rests)
    still = rest_mask(prep, t.size)
    step = max(1, int(round(SEGMENT_S * fs)))
    segs = []
    for lo in range(0, t.size - step // 2, step):
        hi = min(lo + step, t.size)
        if np.mean(still[lo:hi]) > 0.5:
            continue
        segs.append({"t_s": [float(t[lo]), float(t[hi - 1])], "slow_external_acc_rms_m_s2": _acc_rms(lp[lo:hi], 0.0)})
    segs.sort(key=lambda s: -s["slow_external_acc_rms_m_s2"])
    return Coaching(total, tremor, slow, sig, sig_ideal, tuple(segs[:top]))
