"""The data-derived noise-inflation figure: "why everyone multiplies by 10".

An estimator that propagates the sensor with a noise model (white density N, perhaps a bias random
walk K, as a Kalibr ``imu.yaml`` gives a VIO filter) predicts the spread of the mean signal over
an interval τ; between two consecutive intervals the predicted difference has variance
2 σ²_A,model(τ) (the bias is the same in both, so an unknown constant bias cancels).  On the
recording the same difference has variance 2 σ̂²_A(τ) = 4 ν̂²(τ).  The NEES of that prediction is
σ̂²_A/σ²_A,model, so the factor that makes it consistent (NEES = 1) at τ is

    F(τ) = σ̂_A(τ) / σ_A,model(τ),

and an estimator whose aiding arrives every h seconds needs max_{τ ≤ h} F(τ) on its white density
(its random walk can absorb part of it; the figure is for scaling N alone, the usual practice).
The 1σ of F from the wavelet variance's covariance is F·σ(ν̂)/(2ν̂).
"""

from __future__ import annotations

import numpy as np

__all__ = ["inflation_table", "inflation_factor", "HORIZONS_S"]

HORIZONS_S = (0.1, 1.0, 10.0, 100.0, 1000.0)


def inflation_factor(nu2_observed: np.ndarray, nu2_assumed: np.ndarray) -> np.ndarray:
    """F(τ) = √(ν̂²/ν²_assumed) per scale (ν² = σ²_A/2, so the ratio is that of Allan deviations)."""
    return np.sqrt(np.asarray(nu2_observed) / np.maximum(np.asarray(nu2_assumed), 1e-300))


def inflation_table(axes, rate_hz: float, assumed: dict[str, float] | None = None) -> dict:
    """For each axis: F(τ) for three estimator noise models — white only (the identified N),
    white + random walk (the identified N and K: what a Kalibr imu.yaml holds), and the chosen
    model (≈ 1 when it is honest) — on every scale, and max F over τ ≤ h for ``HORIZONS_S``.
    ``assumed``: {"white_noise": N, "random_walk": K} of a given estimator instead."""
    from gyrosim.effects import RandomWalk, WhiteNoise

    out = {"definition": "F(τ) = observed Allan deviation / the estimator model's, at Allan cluster time τ; "
                         "max over τ ≤ h for an estimator aided every h s", "horizons_s": list(HORIZONS_S), "axes": []}
    for a in axes:
        sel = a.selection
        wv = sel.wv
        n_ = assumed.get("white_noise") if assumed else a.value("white_noise", "density")
        k_ = assumed.get("random_walk", 0.0) if assumed else a.value("random_walk", "value")
        white = WhiteNoise(density=np.full(3, n_)).haar_wavelet_variance(wv.m, wv.dt_s)[0]
        rw = RandomWalk(value=np.full(3, k_)).haar_wavelet_variance(wv.m, wv.dt_s)[0]
        rel = np.sqrt(np.diag(sel.sigma)) / wv.nu2 / 2
        tau_allan = wv.m * wv.dt_s
        rows = {}
        for label, nu_model in (("white_only", white), ("white_plus_random_walk", white + rw),
                                ("chosen_model", sel.chosen.nu2_model)):
            f = inflation_factor(wv.nu2, nu_model)
            horizon = {}
            for h in HORIZONS_S:
                sel_tau = tau_allan <= h
                if sel_tau.any() and h <= tau_allan[-1] * 2:
                    i = int(np.argmax(np.where(sel_tau, f, -np.inf)))
                    horizon[str(h)] = {
                        "factor": float(f[i]),
                        "sigma": float(f[i] * rel[i]),
                        "at_tau_s": float(tau_allan[i]),
                    }
            rows[label] = {"factor": f.tolist(), "sigma": (f * rel).tolist(), "max_over_horizon": horizon}
        out["axes"].append({"axis": a.axis, "allan_tau_s": tau_allan.tolist(), "assumed": {"white_noise": n_,
                            "random_walk": k_}, **rows})
    return out
