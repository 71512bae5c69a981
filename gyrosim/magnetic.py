"""The magnetic field the virtual board moves through: the Earth's field plus local anomalies.

* **Earth field** (uniform over the room): either given as an ENU vector in µT, or computed for a
  location and date with the World Magnetic Model (NOAA/BGS WMM 2010–2025, through ``pygeomag``,
  whose coefficient files ship inside the package: nothing is downloaded).  WMM gives the field in
  north–east–down nT; here it is turned into ENU µT: B_enu = (B_e, B_n, −B_d) / 1000.
* **Local anomalies**: point dipoles at fixed room positions (navigation frame ENU, m), e.g. a
  steel object magnetised by the Earth's field.  The field of a dipole of moment m (A·m²) at
  offset r from it is (Jackson, *Classical Electrodynamics*, 3rd ed., eq. 5.56)

      B(r) = μ₀/(4π) · (3 r̂ (m·r̂) − m) / |r|³

  so the field changes as the hand moves the board around: the disturbance a calibration must
  report, not absorb.  A soft-iron sphere of radius a in a uniform field B₀ (μ_r ≫ 1) carries the
  induced moment m = 4π a³ B₀ / μ₀ (Jackson §5.11): :meth:`Dipole.ferrous_sphere`.
* **A magnet attached to the board** is the other case: its field turns with the board — a hard
  iron that switches on (:class:`gyrosim.effects.AttachedMagnet`, a sensor effect;
  :func:`attached_magnet_from_text` reads it from the command line).

MuJoCo's ``magnetometer`` sensor reads the uniform part (``option/magnetic``, tesla, world frame)
in the site frame; :meth:`MagneticEnvironment.anomaly_nav_ut` adds the rest at the site positions.
"""

from __future__ import annotations

import datetime as _dt
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .errors import GyrosimError

__all__ = ["Dipole", "MagneticEnvironment", "DEFAULT_EARTH_FIELD_ENU_UT", "wmm_field_enu_ut", "environment_from_text",
           "attached_magnet_from_text"]

MU0_OVER_4PI = 1e-7  # T·m/A
MU0 = 4 * math.pi * MU0_OVER_4PI

# 48° N, central Europe (WMM-class values: 20 µT north, 44 µT down); the model file's default
DEFAULT_EARTH_FIELD_ENU_UT = (1.5, 20.0, -44.0)


def _vec3(v: Any, name: str) -> np.ndarray:
    a = np.asarray(v, dtype=float).reshape(-1)
    if a.size != 3 or not np.all(np.isfinite(a)):
        raise GyrosimError(f"{name} needs 3 finite values, got {np.asarray(v).tolist()}")
    return a


def _decimal_year(date: _dt.date | _dt.datetime | float | str) -> float:
    if isinstance(date, (int, float)):
        return float(date)
    if isinstance(date, str):
        try:
            date = _dt.date.fromisoformat(date)
        except ValueError as exc:
            raise GyrosimError(f"date {date!r}: use ISO format YYYY-MM-DD or a decimal year") from exc
    start = _dt.date(date.year, 1, 1)
    days = (_dt.date(date.year + 1, 1, 1) - start).days
    d = date.date() if isinstance(date, _dt.datetime) else date
    return date.year + (d - start).days / days


def wmm_field_enu_ut(latitude_deg: float, longitude_deg: float, height_m: float,
                     date: _dt.date | float | str) -> tuple[np.ndarray, str]:
    """Earth field (µT, ENU) and a provenance string from the World Magnetic Model (pygeomag).

    Geodetic latitude/longitude (°), height above the WGS-84 ellipsoid (m), date (ISO string,
    ``datetime.date`` or decimal year).  The model epoch is chosen from the date (WMM 2010, 2015,
    2020, 2025; each valid five years); a date outside 2010–2030 is refused.
    """
    from pygeomag import GeoMag

    if not (-90.0 <= latitude_deg <= 90.0 and -180.0 <= longitude_deg <= 360.0):
        raise GyrosimError(f"location {latitude_deg}°, {longitude_deg}°: latitude must be within ±90°, longitude ±180°")
    year = _decimal_year(date)
    if not 2010.0 <= year < 2030.0:
        raise GyrosimError(f"date {year:.2f} is outside the World Magnetic Model's 2010–2030 span; "
                           "give the field as an ENU vector in µT instead")
    epoch = 2010 + 5 * int((year - 2010) // 5)
    try:
        geo = GeoMag(base_year=epoch)
        r = geo.calculate(glat=float(latitude_deg), glon=float(longitude_deg), alt=float(height_m) / 1000.0, time=year)
    except (ValueError, FileNotFoundError) as exc:  # pragma: no cover - guarded by the range check above
        raise GyrosimError(
            f"World Magnetic Model failed for {latitude_deg}°, {longitude_deg}°, {year:.2f}: {exc}"
        ) from exc
    enu = np.array([r.y, r.x, -r.z]) / 1000.0  # nT north-east-down → µT east-north-up
    src = (f"WMM{epoch} (pygeomag) at {latitude_deg:.4f}°, {longitude_deg:.4f}°, {height_m:.0f} m, {year:.3f}: "
           f"|B| {r.f / 1000:.2f} µT, inclination {r.i:.2f}°, declination {r.d:.2f}°")
    return enu, src


@dataclass(frozen=True)
class Dipole:
    """A point magnetic dipole fixed in the room: position (m, ENU) and moment (A·m², ENU)."""

    position_m: np.ndarray
    moment_a_m2: np.ndarray
    label: str = "dipole"

    def __post_init__(self) -> None:
        object.__setattr__(self, "position_m", _vec3(self.position_m, "dipole position_m"))
        object.__setattr__(self, "moment_a_m2", _vec3(self.moment_a_m2, "dipole moment_a_m2"))

    @classmethod
    def ferrous_sphere(
        cls, position_m: Any, radius_m: float, earth_enu_ut: Any, label: str = "ferrous sphere"
    ) -> "Dipole":
        """A soft-iron sphere (μ_r ≫ 1) of radius ``radius_m`` magnetised by the Earth field:
        m = 4π a³ B₀ / μ₀ (Jackson §5.11, the μ_r → ∞ limit of 4π a³ (μ_r − 1)/(μ_r + 2) H₀)."""
        if not (math.isfinite(radius_m) and radius_m > 0):
            raise GyrosimError("ferrous_sphere radius_m must be > 0 m")
        b0 = _vec3(earth_enu_ut, "earth_enu_ut") * 1e-6
        return cls(position_m, 4 * math.pi * radius_m**3 * b0 / MU0, label)

    def field_nav_ut(self, points_nav_m: np.ndarray) -> np.ndarray:
        """(N, 3) field (µT, ENU) at the points (N, 3) (m, ENU): B = μ₀/4π (3 r̂(m·r̂) − m)/r³."""
        r = np.asarray(points_nav_m, dtype=float) - self.position_m
        d = np.linalg.norm(r, axis=1, keepdims=True)
        if np.any(d < 1e-3):
            raise GyrosimError(f"the board passes within 1 mm of the {self.label} at {self.position_m.tolist()} m: "
                               "a point dipole is meaningless there; move the anomaly")
        u = r / d
        m = self.moment_a_m2
        return MU0_OVER_4PI * (3 * u * (u @ m)[:, None] - m) / d**3 * 1e6

    def to_dict(self) -> dict[str, Any]:
        return {"position_m": self.position_m.tolist(), "moment_a_m2": self.moment_a_m2.tolist(), "label": self.label}


@dataclass(frozen=True)
class MagneticEnvironment:
    """The session's magnetic field: uniform Earth field (µT, ENU) and optional dipole anomalies."""

    earth_enu_ut: np.ndarray = field(default_factory=lambda: np.array(DEFAULT_EARTH_FIELD_ENU_UT))
    anomalies: tuple[Dipole, ...] = ()
    source: str = "given ENU vector"

    def __post_init__(self) -> None:
        b = _vec3(self.earth_enu_ut, "earth field (ENU, µT)")
        mag = float(np.linalg.norm(b))
        if not 1.0 <= mag <= 1000.0:
            raise GyrosimError(f"earth field magnitude {mag:.4g} µT is not a plausible field in µT (Earth: 22–67 µT); "
                               "give the ENU vector in µT (1 G = 100 µT, 1 nT = 0.001 µT)")
        object.__setattr__(self, "earth_enu_ut", b)
        object.__setattr__(self, "anomalies", tuple(self.anomalies))

    @classmethod
    def at(cls, latitude_deg: float, longitude_deg: float, height_m: float = 0.0,
           date: _dt.date | float | str = "2025-01-01", anomalies: tuple[Dipole, ...] = ()) -> "MagneticEnvironment":
        """The WMM field at a location and date (:func:`wmm_field_enu_ut`)."""
        b, src = wmm_field_enu_ut(latitude_deg, longitude_deg, height_m, date)
        return cls(b, anomalies, src)

    @property
    def magnitude_ut(self) -> float:
        return float(np.linalg.norm(self.earth_enu_ut))

    @property
    def inclination_deg(self) -> float:
        """Dip angle (°), positive when the field points down (northern hemisphere)."""
        b = self.earth_enu_ut
        return math.degrees(math.atan2(-b[2], math.hypot(b[0], b[1])))

    def anomaly_nav_ut(self, points_nav_m: np.ndarray) -> np.ndarray:
        """Sum of the anomalies' fields (µT, ENU) at the points (m, ENU); zeros without anomalies."""
        pts = np.asarray(points_nav_m, dtype=float)
        out = np.zeros_like(pts)
        for d in self.anomalies:
            out += d.field_nav_ut(pts)
        return out

    def field_nav_ut(self, points_nav_m: np.ndarray) -> np.ndarray:
        """Total field (µT, ENU) at the points (m, ENU)."""
        return self.earth_enu_ut + self.anomaly_nav_ut(points_nav_m)

    def to_dict(self) -> dict[str, Any]:
        return {"earth_enu_ut": self.earth_enu_ut.tolist(), "source": self.source,
                "anomalies": [a.to_dict() for a in self.anomalies]}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "MagneticEnvironment":
        return cls(np.asarray(d["earth_enu_ut"], float), tuple(Dipole(**a) for a in d.get("anomalies", [])),
                   d.get("source", "given ENU vector"))


def _numbers(text: str, what: str, counts: tuple[int, ...]) -> list[str]:
    parts = [p.strip() for p in str(text).split(",")]
    if len(parts) not in counts:
        raise GyrosimError(f"{what} {text!r}: expected {' or '.join(map(str, counts))} comma-separated values")
    return parts


def environment_from_text(field_enu_ut: str | None = None, location: str | None = None,
                          anomalies: tuple[str, ...] | list[str] = ()) -> MagneticEnvironment:
    """A :class:`MagneticEnvironment` from command-line text (``gyrosim simulate``):

    * ``field_enu_ut`` "E,N,U" in µT, or ``location`` "LAT,LON[,HEIGHT_M[,YYYY-MM-DD]]" (WMM);
    * each anomaly "X,Y,Z,RADIUS_M": a ferrous sphere at the room position X,Y,Z (m, ENU)
      magnetised by the Earth field (:meth:`Dipole.ferrous_sphere`).
    """
    if field_enu_ut and location:
        raise GyrosimError("give either the field as an ENU vector (--mag-field) or a location (--location), not both")
    if location:
        p = _numbers(location, "location", (2, 3, 4))
        try:  # (the range and date checks raise GyrosimError below, outside this try)
            lat, lon = float(p[0]), float(p[1])
            height = float(p[2]) if len(p) > 2 else 0.0
        except ValueError as exc:
            raise GyrosimError(
                f"location {location!r}: LAT,LON[,HEIGHT_M[,YYYY-MM-DD]] with numbers in degrees and m"
            ) from exc
        env = MagneticEnvironment.at(lat, lon, height, p[3] if len(p) > 3 else "2025-01-01")
    elif field_enu_ut:
        try:
            vec = np.array([float(v) for v in _numbers(field_enu_ut, "field", (3,))])
        except GyrosimError:
            raise
        except ValueError as exc:
            raise GyrosimError(f"field {field_enu_ut!r}: three numbers E,N,U in µT") from exc
        env = MagneticEnvironment(vec)
    else:
        env = MagneticEnvironment()
    dips = []
    for a in anomalies:
        parts = _numbers(a, "anomaly", (4,))
        try:
            x, y, z, r = (float(v) for v in parts)
        except ValueError as exc:
            raise GyrosimError(f"anomaly {a!r}: four numbers X,Y,Z (m, ENU) and RADIUS_M") from exc
        dips.append(Dipole.ferrous_sphere([x, y, z], r, env.earth_enu_ut, label=f"ferrous sphere r={r:g} m"))
    return MagneticEnvironment(env.earth_enu_ut, tuple(dips), env.source)


def attached_magnet_from_text(text: str):
    """An :class:`gyrosim.effects.AttachedMagnet` from ``gyrosim simulate --attach-magnet``'s text
    "T_ON,HX,HY,HZ[,T_OFF]": attached at T_ON s (taken off at T_OFF s, else it stays), its field
    HX,HY,HZ in µT in the body frame (right, forward, up)."""
    from .effects import AttachedMagnet

    parts = _numbers(text, "attached magnet", (4, 5))
    try:
        vals = [float(v) for v in parts]
    except ValueError as exc:
        raise GyrosimError(f"attached magnet {text!r}: T_ON,HX,HY,HZ[,T_OFF] — numbers in s and µT") from exc
    return AttachedMagnet(value=vals[1:4], t_on_s=vals[0], t_off_s=vals[4] if len(vals) == 5 else None)
