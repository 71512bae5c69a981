"""Text summary and wavelet-variance plot of a :class:`~calib.noise.identify.NoiseIdentification`,
and the temperature-trend check of a static record."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from calib.noise.gmwm import NOISE_TERMS
from calib.noise.identify import NoiseIdentification
from calib.noise.units import datasheet_unit, representations

__all__ = ["summary_lines", "plot_noise", "temperature_trend_c"]

def summary_lines(res: NoiseIdentification) -> list[str]:
    """One line per parameter: value and 95 % interval in datasheet units, and SI."""
    triad = "gyro" if res.triad == "gyro" else "accelerometer"
    out = [f"  {triad}, {res.duration_s:.0f} s at {res.rate_hz:g} Hz; status {res.status}"]
    for a in res.axes:
        out.append(f"  axis {a.axis}: model {a.model}" + ("" if a.consistent else
                   f"  (INCONSISTENT: objective p = {a.objective_p_value:.1e}, no candidate describes this axis)"))
        for p in a.parameters:
            u = datasheet_unit(p.kind, p.field, triad)
            conv = [representations(p.kind, p.field, v, res.rate_hz, triad)[u] for v in (p.value,) + p.ci95]
            out.append(
                f"    {p.kind}.{p.field}{'' if p.index == 0 else f'[{p.index}]'} = {conv[0]:.4g} {u} "
                f"(95 %: {conv[1]:.4g} … {conv[2]:.4g}; ±{100 * p.rel_sigma:.1f} % 1σ)  = {p.value:.4g} {p.unit}"
            )
    return out


def plot_noise(res: NoiseIdentification, path: str | Path) -> Path:
    """Allan deviation √(2ν̂²) per axis with 1σ bars, the chosen model and its terms."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axs = plt.subplots(1, len(res.axes), figsize=(5 * len(res.axes), 4.5), squeeze=False)
    for ax, a in zip(axs[0], res.axes):
        sel = a.selection
        wv = sel.wv
        tau = wv.m * wv.dt_s
        sd = np.sqrt(np.diag(sel.sigma))
        ax.errorbar(tau, np.sqrt(2 * wv.nu2), yerr=np.sqrt(2 * wv.nu2) * sd / wv.nu2 / 2, fmt="k.", label="data")
        ax.loglog(tau, np.sqrt(2 * sel.chosen.nu2_model), "r-", label=f"model {a.model}")
        logp = sel.chosen.log_params
        i = 0
        for kind in sel.chosen.kinds:
            cls = NOISE_TERMS[kind]
            k = len(cls.noise_parameters)
            e = cls(**{f: np.full(3, math.exp(v)) for f, v in zip(cls.noise_parameters, logp[i:i + k])})
            ax.loglog(tau, np.sqrt(2 * e.haar_wavelet_variance(wv.m, wv.dt_s)[0]), ":", lw=1, label=kind)
            i += k
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("τ (s)")
        ax.set_ylabel("Allan deviation (SI)")
        ax.set_title(f"axis {a.axis}")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def temperature_trend_c(t_s: np.ndarray, temp_c: np.ndarray | None) -> float | None:
    """Change of temperature over the record by a straight-line fit (°C), None without a channel."""
    if temp_c is None:
        return None
    temp = np.asarray(temp_c, float)
    ok = np.isfinite(temp)
    if ok.sum() < 3:
        return None
    slope = np.polyfit(t_s[ok] - t_s[0], temp[ok], 1)[0]
    return float(slope * (t_s[-1] - t_s[0]))
