"""Planning a north-finding: the accuracy limit against latitude and rest time ("effect
of latitude on gyroscopic theodolite": the north-seeking torque — here the horizontal Earth rate
Ω_E cos L — falls with latitude, and with it the accuracy, until near 75–90° north cannot be found).

For a level table with P equally spaced positions held τ each (moves of ``move_s`` between), the
limit of :mod:`calib.instruments.northfind` is

    σ_ψ(L, τ) = σ_res(τ) / (Ω_E cos L),     σ_res² = ½ tr Cov(ŵ)   (averaged over headings),

Cov(ŵ) from the gyro's noise terms through the covariance of the hold means
(:mod:`calib.noise.window_means`).  For white noise alone σ_res = N/√(Pτ); flicker sets a floor and a
random walk makes long holds worse again, so a gyro has a best σ_res and therefore a latitude
above which no rest time reaches a requested accuracy X:

    L_max = arccos(σ_res / (Ω_E X)).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from gyrosim.effects import EARTH_RATE_RAD_S

from calib.instruments.northfind_design import Design, turning_design
from calib.noise.allan import NoiseTerms

__all__ = ["procedure_sigma_res", "limit_sigma_deg", "rest_time_needed", "max_latitude_deg", "latitude_curve",
           "plot_latitude_curve"]

HOLD_GRID_S = np.logspace(0.0, 5.0, 41)    # 1 s … 28 h per position


def procedure_sigma_res(
    noise: tuple[NoiseTerms, ...], hold_s: float, positions: int = 4, move_s: float = 10.0
) -> float:
    """σ_res (rad/s, heading-averaged) of P equally spaced positions held ``hold_s`` each on a
    level table (body z up), the moves ``move_s`` long.  Evaluated at a planning rate of
    min(1 Hz, 400/hold_s) (at least 4 samples a hold): the white term N²/τ does not depend on
    the rate, and flicker above 200/τ reaches a τ-long mean through sinc² < 3e-6 of its power."""
    if positions < 2:
        raise ValueError("north-finding needs at least two positions")
    rate = max(4.0 / hold_s, min(1.0, 400.0 / hold_s))
    n_hold = max(1, int(round(hold_s * rate)))
    n_move = int(round(move_s * rate))
    starts = np.arange(positions) * (n_hold + n_move)
    windows = np.stack([starts, starts + n_hold], axis=1)
    alpha = 2 * math.pi * np.arange(positions) / positions
    basis = np.array([[1.0, 0, 0], [0, 1.0, 0]])
    d = Design(windows, turning_design(alpha), basis, np.zeros(2), np.array([0.0, 1.0]), rate, int(windows[-1, 1]))
    return float(math.sqrt(np.trace(d.w_covariance(noise)) / 2))


def limit_sigma_deg(noise: tuple[NoiseTerms, ...], latitude_deg: float, hold_s: float, positions: int = 4,
                    move_s: float = 10.0) -> float:
    """σ_ψ (°) of the procedure at a latitude (module docstring)."""
    return math.degrees(procedure_sigma_res(noise, hold_s, positions, move_s)
                        / (EARTH_RATE_RAD_S * math.cos(math.radians(latitude_deg))))


def max_latitude_deg(sigma_res_rad_s: float, accuracy_deg: float) -> float | None:
    """Highest latitude where σ_res/(Ω_E cos L) ≤ accuracy; None if not even at the equator."""
    ratio = sigma_res_rad_s / (EARTH_RATE_RAD_S * math.radians(accuracy_deg))
    return math.degrees(math.acos(ratio)) if ratio <= 1 else None


def rest_time_needed(noise: tuple[NoiseTerms, ...], latitude_deg: float, accuracy_deg: float, rate_hz: float = 1.0,
                     positions: int = 4, move_s: float = 10.0) -> tuple[float | None, str]:
    """(hold per position in s, or None if no rest time reaches the accuracy; a sentence for the user).

    Searches τ on a log grid 1 s … 28 h, then bisects (in log τ) between the grid points."""
    del rate_hz  # planning rate: see procedure_sigma_res
    positions = max(positions, 2)
    target = math.radians(accuracy_deg) * EARTH_RATE_RAD_S * math.cos(math.radians(latitude_deg))
    sig = np.array([procedure_sigma_res(noise, t, positions, move_s) for t in HOLD_GRID_S])
    best = int(np.argmin(sig))
    best_deg = math.degrees(sig[best] / (EARTH_RATE_RAD_S * math.cos(math.radians(latitude_deg))))
    if sig[best] > target:
        return None, (f"no rest time reaches {accuracy_deg:g}° at latitude {latitude_deg:g}° with this gyro: the best "
                      f"within {positions} positions × ≤ {HOLD_GRID_S[-1] / 3600:.0f} h is {best_deg:.3g}° "
                      f"({positions} × {HOLD_GRID_S[best]:.0f} s); a better gyro is needed")
    k = int(np.argmax(sig <= target))
    if k == 0:
        tau = float(HOLD_GRID_S[0])
    else:
        lo, hi = math.log(HOLD_GRID_S[k - 1]), math.log(HOLD_GRID_S[k])
        for _ in range(12):
            mid = 0.5 * (lo + hi)
            if procedure_sigma_res(noise, math.exp(mid), positions, move_s) <= target:
                hi = mid
            else:
                lo = mid
        tau = math.exp(hi)
    return tau, (f"{accuracy_deg:g}° at latitude {latitude_deg:g}° needs {positions} positions × {tau:.0f} s of rest "
                 f"({positions * tau / 60:.1f} min in all)")


def latitude_curve(noise: tuple[NoiseTerms, ...], latitudes_deg: np.ndarray, hold_s: float, positions: int = 4,
                   move_s: float = 10.0) -> np.ndarray:
    """σ_ψ (°) at each latitude for one procedure ("Effect of latitude on gyroscopic theodolite")."""
    sr = procedure_sigma_res(noise, hold_s, positions, move_s)
    return np.degrees(sr / (EARTH_RATE_RAD_S * np.cos(np.radians(latitudes_deg))))


def plot_latitude_curve(
    curves: dict[str, tuple[np.ndarray, np.ndarray]],
    path: str | Path,
    *,
    accuracy_deg: float | None = None,
    points: dict[str, tuple[np.ndarray, np.ndarray]] | None = None,
    title: str = "North-finding limit against latitude",
) -> Path:
    """Log plot of σ_ψ (°) against latitude per sensor, the requested accuracy as a line, and
    Monte Carlo RMS errors as points (same colour as their curve)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 5))
    colours = {}
    for name, (lat, sig) in curves.items():
        (line,) = ax.semilogy(lat, sig, label=name)
        colours[name] = line.get_color()
    for name, (lat, rms) in (points or {}).items():
        key = next((k for k in colours if k.startswith(name)), None)
        ax.semilogy(
            lat, rms, "o", color=colours.get(key, "k"), ms=6, mfc="none", label=f"{name}: Monte Carlo RMS error"
        )
    if accuracy_deg is not None:
        ax.axhline(accuracy_deg, color="k", ls="--", lw=1, label=f"requested accuracy {accuracy_deg:g}°")
    ax.axhline(math.degrees(1 / 3), color="0.5", ls=":", lw=1, label="19°: the gyro cannot see North")
    ax.axhline(180 / math.sqrt(3), color="0.5", ls="-.", lw=1, label="104°: RMS of a random heading")
    ax.set_xlabel("latitude (°)")
    ax.set_ylabel("heading σ (°)")
    ax.set_xlim(0, 80)
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
