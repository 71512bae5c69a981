"""The magnetometer loop's round steps (:class:`MagSteps`, run by :mod:`calib.closeloop.driver`),
under the gyro loop's rules where they apply:

1. **gate** (:mod:`calib.closeloop.mag.identify`): every component of the candidate at its largest
   plausible size must show at 3σ against the current model.
2. **held-out gain**: G = n_eff ln(RSS₀/RSS₁) − Δp ln n_eff on the held-out stretches (n_eff = rows /
   τ_int of the richest model's held-out residual, as the gyro loop counts it); a positive G with a
   fitted size beyond the plausible one by 3σ is refused as a proxy.
3. **confounding**: the best candidate and any other with G > 0 that explains the same part
   (overlap ≥ ½, or one adds nothing beyond the other: the gyro loop's definition,
   :mod:`calib.closeloop.confounding`) form a group; rule: the member that explains all another does
   and more, else the larger gain (all magnetometer candidates read their cause through the same
   channel, the reference field).
4. **acceptance on every metric** (:mod:`calib.closeloop.mag.metrics`): the model with the pick must
   leave no held-out metric worse beyond its noise against the current and the declared model
   (:func:`calib.closeloop.driver.accept_on_every_metric`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from calib.closeloop.confounding import MIN_OVERLAP, ConfoundedGroup, MemberEvidence, contribution_correlation, overlap
from calib.closeloop.driver import CandidateScore, NotTaken, Rejection, Scoring, accept_on_every_metric
from calib.closeloop.fit import integrated_time
from calib.closeloop.identify import Excitation
from calib.closeloop.mag.fit import MagFit, fit_mag
from calib.closeloop.mag.identify import mag_excitation
from calib.closeloop.mag.metrics import mag_metrics
from calib.closeloop.mag.reference import MagReference
from calib.closeloop.mag.terms import mag_term
from calib.closeloop.metrics import MetricChange, MetricSums

__all__ = ["MagSetup", "MagSteps", "MAG_RULE", "noise_of"]

MAG_RULE = ("a member that explains all another does and more first; else the larger held-out gain (every magnetometer "
            "candidate reads its cause through the same channel: the reference field)")


@dataclass(frozen=True)
class MagSetup:
    """What every step shares: the reference, the samples left out as local disturbances, n_eff of
    the held-out rows and σ_w of the gate (µT; :mod:`calib.closeloop.mag.identify`)."""

    ref: MagReference
    exclude: np.ndarray
    n_eff: float
    noise_ut: float

    @property
    def fit_rows(self) -> np.ndarray:
        return self.ref.rows(held=False, exclude=self.exclude)

    @property
    def held_rows(self) -> np.ndarray:
        return self.ref.rows(held=True, exclude=self.exclude)

    def fit(self, kinds: tuple[str, ...], start: MagFit | None = None, rows: np.ndarray | None = None) -> MagFit:
        """The model ``kinds`` fitted on ``rows`` (default: the fit rows), started from ``start``'s θ."""
        theta0 = None
        if start is not None:
            extra = sum(mag_term(k).n_params for k in kinds[len(start.kinds):])
            theta0 = np.concatenate([start.theta, np.zeros(extra)])
        return fit_mag(self.ref, kinds, self.fit_rows if rows is None else rows, theta0)

    def gain(self, before: MagFit, after: MagFit) -> float:
        """G = n_eff ln(RSS₀/RSS₁) − Δp ln n_eff on the held-out rows (−∞: nothing added)."""
        rss0, rss1 = before.rss(self.held_rows), after.rss(self.held_rows)
        dp = after.rank - before.rank
        if dp <= 0 or rss1 <= 0:
            return -math.inf
        return self.n_eff * math.log(rss0 / rss1) - dp * math.log(self.n_eff)

    def rms(self, f: MagFit) -> float:
        """Held-out field residual RMS (µT)."""
        r = f.residual[self.held_rows]
        return float(np.sqrt(np.mean(r**2))) if r.size else math.nan

    def metrics(self, f: MagFit) -> dict[str, MetricSums]:
        return mag_metrics(self.ref, f, self.exclude)


def noise_of(ref: MagReference, f: MagFit, exclude: np.ndarray) -> tuple[float, float]:
    """(n_eff of the held-out rows, σ_w of the gate) from the richest model's held-out residual:
    τ_int the mean integrated autocorrelation time over the residual's axes, n_eff = rows / τ_int,
    σ_w = max(the magnetometer's white noise, RMS · √τ_int)."""
    held = ref.rows(held=True, exclude=exclude)
    r = f.residual[held]
    tau = max(float(np.mean([integrated_time(r[:, a]) for a in range(r.shape[1])])), 1.0)
    sigma = float(np.sqrt(np.mean(r**2))) * math.sqrt(tau)
    return max(r.size / tau, 2.0), max(ref.noise_ut, sigma)


def _implausible(kind: str, f: MagFit) -> str | None:
    """Why a fitted size is a proxy: |θ̂| − 3σ beyond the largest plausible size (None: plausible)."""
    term = mag_term(kind)
    th = f.theta[-term.n_params:]
    sig = np.sqrt(np.maximum(np.diag(f.cov), 0.0))[-term.n_params:]
    over = np.abs(th) - 3 * sig > term.plausible_max
    if not np.any(over):
        return None
    j = int(np.argmax(np.abs(th)))
    fac, unit = term.display
    return (f"fitted {kind} reaches {th[j] * fac:.3g} {unit}, beyond the largest plausible size "
            f"({term.plausible_max * fac:.3g} {unit}) by more than 3σ: a proxy for something else, not this effect")


@dataclass(frozen=True)
class MagSteps:
    """:class:`calib.closeloop.driver.SensorSteps` on the magnetometer's field residual; the work a
    score step keeps is every scored candidate's fit (kind → :class:`MagFit`)."""

    setup: MagSetup
    rounds_on_empty_pool: bool = False

    def score(self, state: MagFit, pool: Mapping[str, str], rnd: int) -> Scoring[str, dict[str, MagFit]]:
        """Steps 1–2 of the module docstring, candidate by candidate in pool order."""
        c = self.setup
        fits: dict[str, MagFit] = {}
        table: list[CandidateScore] = []
        excitations: list[Excitation] = []
        live: dict[str, float] = {}
        not_taken: dict[str, NotTaken] = {}
        for k in pool:
            exc = mag_excitation(c.ref, state, k, c.fit_rows, c.noise_ut)
            excitations.append(exc)
            if not exc.identifiable:
                not_taken[k] = NotTaken("not_identifiable", exc.reason)
                continue
            f = c.fit(state.kinds + (k,), state)
            gain = c.gain(state, f)
            fits[k] = f
            why = _implausible(k, f) if gain > 0 else None
            table.append(CandidateScore(k, gain if math.isfinite(gain) else None, f.rank - state.rank, c.rms(state),
                                        c.rms(f), c.n_eff, why))
            if gain > 0 and not why:
                live[k] = gain
            elif why:
                not_taken[k] = NotTaken("implausible", why)
        table.sort(key=lambda s: -(s.gain if s.gain is not None else -math.inf))
        return Scoring(tuple(table), tuple(excitations), live, not_taken, dict(pool), fits)

    def best(self, live: Mapping[str, float], scoring: Scoring[str, dict[str, MagFit]]) -> str:
        return max(live, key=live.get)

    def confounded(self, state: MagFit, scoring: Scoring[str, dict[str, MagFit]], live: Mapping[str, float],
                   best: str, rnd: int) -> tuple[str, ConfoundedGroup | None]:
        """Step 3: for each other live c, fitted alone and together with b (RSS on the held-out rows),
        overlap = (E_b − (RSS(c) − RSS(b, c))) / min(E_b, E_c) with E_x = RSS₀ − RSS(x), and the
        conditional gains G(c | b), G(b | c) (:mod:`calib.closeloop.confounding`)."""
        c = self.setup
        fits = scoring.work
        held = c.held_rows
        rss0 = state.rss(held)
        members, wider = [], []
        for k in live:
            if k == best:
                continue
            fk = fits[k]
            both = c.fit(state.kinds + (best, k), state)
            rc = fk.rss(held)
            share = overlap(rss0, fits[best].rss(held), rc, both.rss(held))
            g_cb, g_bc = c.gain(fits[best], both), c.gain(fk, both)
            if share >= MIN_OVERLAP or g_cb <= 0 or g_bc <= 0:
                rho = contribution_correlation(state.residual[held], fits[best].residual[held], fk.residual[held])
                members.append(MemberEvidence(k, "reference_field", live[k], 1 - rc / rss0, float(share), float(g_cb),
                                              float(g_bc), rho, mag_term(k).separated_by))
                if g_bc <= 0 < g_cb:
                    wider.append(k)
        if not members:
            return best, None
        chosen = max(wider, key=lambda k: live[k]) if wider else best
        own = MemberEvidence(best, "reference_field", live[best], 1 - fits[best].rss(held) / rss0, 1.0,
                             live[best], live[best], 1.0, mag_term(best).separated_by)
        ev = (own,) + tuple(members)
        names = [m.effect for m in ev]
        seps = "; or ".join(dict.fromkeys(m.separated_by for m in ev))
        why = (f"{', '.join(names)} explain the same part of the held-out field residual on this recording; chosen "
               f"{chosen} by the rule: {MAG_RULE}")
        return chosen, ConfoundedGroup(rnd, chosen, ev, MAG_RULE, seps, why)

    def with_term(self, state: MagFit, scoring: Scoring[str, dict[str, MagFit]], kind: str) -> MagFit:
        return scoring.work[kind]

    def accept(self, state: MagFit, declared: MagFit, new: MagFit, kind: str, rnd: int
               ) -> tuple[tuple[MetricChange, ...], Rejection | None]:
        c = self.setup
        caveat = "the reference attitude's own frame and errors" if c.ref.source == "optical" else None
        return accept_on_every_metric(c.metrics(state), c.metrics(declared) if state is not declared else None,
                                      c.metrics(new), kind, rnd, "the magnetometer's residual rows", caveat)
