"""Adding an effect touches one file: a toy effect class defined here only is simulated by the sensor
model (and read from a preset in datasheet units), compensated by a Calibration, and proposed — named
first, in its own display unit — by the closed loop, with no other module edited.

The toy: an even-order rate rectification (a vibrating gyro's output shifts with the square of
its rate; the vocabulary's scale_nonlinearity is the odd k x|x|, so nothing there spans it),

    δ_i = k_i ω_i²,   k in 1/(rad/s),

    ∂δ_i/∂ω_i = 2 k_i ω_i (compensation's Newton step), ∂δ_i/∂k_i = ω_i² (the loop's regressor).

Tolerances: (a) the simulated difference with and without the toy is δ(ω_true) to rounding (1e-12 rad/s:
the other effects draw the same streams); (b) compensation with the device's true effects leaves the white
noise only, passed through (I + S + N)⁻¹: RMS within 1.5 % of N √f_s ‖(I + S + N)⁻¹‖_F/√3 (17101
samples × 3 axes: the sample RMS has a relative σ of 1/√(2·51303) ≈ 0.3 %, so 5σ), and what compensating
the toy removes is its δ (correlation > 0.99; only the 2–5 % axis errors distort it); (c) the loop's
estimate within 4σ̂ of the truth (the suite's tolerance, tests/closeloop/test_closeloop.py).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np
import pytest
from conftest import session

from gyrosim.calibration import Calibration
from gyrosim.effects import EFFECTS, VectorEffect, unregister_effect
from gyrosim.sensor_model import load_sensor, stored_sensor_model
from gyrosim.simulate import apply_sensor

from calib.closeloop import run_closeloop
from calib.closeloop.suite import sensor_with

TOY_K = np.array([2e-3, -1.5e-3, 2.5e-3])  # 1/(rad/s): ~0.5–1 °/s at the schedule's 2–3 rad/s


@pytest.fixture(scope="module")
def toy():
    """The toy effect class, registered for this module only (defined at test time, so no other test
    module ever sees it in the vocabulary) and removed again afterwards."""

    @dataclass(frozen=True)
    class ToyRateSquared(VectorEffect):
        """Even-order rate rectification δ_i = k_i ω_i² (module docstring)."""

        kind: ClassVar[str] = "toy_rate_squared"
        quantities: ClassVar[dict[str, str]] = {"gyro": "per_rate"}
        display_units: ClassVar[dict[str, tuple[float, str]]] = {"gyro": (1e3, "‰/(rad/s)")}
        pointwise: ClassVar[bool] = True
        labels: ClassVar[tuple[str, str]] = ("rectification", "rectification sigma")

        def delta(self, x, ctx, rng=None):
            return self.value * x * x

        def delta_dx(self, x, ctx):
            return (2.0 * self.value * x)[:, :, None] * np.eye(3)[None]

        def sensitivity(self, x, ctx):
            return (x * x)[:, :, None] * np.eye(3)[None]

    assert EFFECTS["toy_rate_squared"] is ToyRateSquared
    yield ToyRateSquared
    unregister_effect("toy_rate_squared")
    assert "toy_rate_squared" not in EFFECTS


@pytest.fixture(scope="module")
def recordings(toy):
    """(truth, without the toy, with the toy) on the closed-loop suite's base device, same streams."""
    truth = session("typical")
    base = sensor_with(None)
    with_toy = replace(base, gyro=base.gyro + (toy(value=TOY_K),))
    return (truth, apply_sensor(truth, base, np.random.default_rng(7)),
            apply_sensor(truth, with_toy, np.random.default_rng(7)))


def test_toy_effect_is_simulated_and_read_from_a_preset_in_its_units(toy, recordings, tmp_path):
    truth, without, with_toy = recordings
    expected = toy(value=TOY_K).delta(truth.truth.omega_body_rad_s, None)
    assert np.max(np.abs(with_toy.gyro_rad_s - without.gyro_rad_s - expected)) < 1e-12
    assert np.sqrt(np.mean(expected**2)) > 0.3 * np.radians(0.083)  # a third of the white noise's RMS: no no-op
    stored = stored_sensor_model(with_toy.meta)  # the recording names the device's toy (serialised, rebuilt)
    assert [e.kind for e in stored.gyro][-1] == "toy_rate_squared"
    np.testing.assert_array_equal(stored.gyro[-1].value, TOY_K)
    # a preset in datasheet units: the class's quantity (per_rate) accepts 1/(deg/s)
    preset = tmp_path / "toy.toml"
    preset.write_text('name = "toy"\n[[gyro]]\neffect = "toy_rate_squared"\nvalue = [1.0, 2.0, 3.0]\n'
                      'unit = "1/(deg/s)"\n')
    np.testing.assert_allclose(load_sensor(str(preset)).gyro[0].value, np.array([1.0, 2.0, 3.0]) * 180 / np.pi,
                               rtol=1e-15)


def test_toy_effect_is_compensated_by_a_calibration(toy, recordings):
    truth, _, rec = recordings
    device = stored_sensor_model(rec.meta).gyro
    noise_rms = float(np.sqrt(np.mean(sum(e.density**2 for e in device if e.is_white_noise) * rec.rate_hz)))
    full = Calibration(gyro=device).compensate(rec)
    r_full = full.gyro_rad_s - truth.truth.omega_body_rad_s
    # white noise ε of equal density on the three axes, seen through M = (I + S + N)⁻¹: E|Mε|²/3 = σ² ‖M‖²_F / 3
    m = np.linalg.inv(np.eye(3) + sum(a for a, _ in (e.affine() or (np.zeros((3, 3)), 0) for e in device)))
    expected_rms = noise_rms * float(np.sqrt(np.sum(m**2) / 3))
    assert abs(float(np.sqrt(np.mean(r_full**2))) / expected_rms - 1.0) < 0.015, expected_rms
    without_toy = Calibration(gyro=tuple(e for e in device if not isinstance(e, toy))).compensate(rec)
    left = (without_toy.gyro_rad_s - truth.truth.omega_body_rad_s - r_full).ravel()  # what the toy's inverse removed
    delta = toy(value=TOY_K).delta(truth.truth.omega_body_rad_s, None).ravel()
    assert np.corrcoef(left, delta)[0, 1] > 0.99  # the toy's δ, seen through (I + S + N)⁻¹ (S, N ≤ 5 %)


def test_toy_effect_is_proposed_first_by_the_loop_in_its_own_unit(toy, recordings):
    _, _, rec = recordings
    res = run_closeloop(rec)
    assert res.found, "the loop added nothing"
    first = res.found[0]
    assert first.effect == "toy_rate_squared", [f.effect for f in res.found]
    est = np.array([first.params[f"toy_rate_squared.value[{i}]"]["value"] for i in range(3)])
    sig = np.array([first.params[f"toy_rate_squared.value[{i}]"]["sigma"] for i in range(3)])
    assert np.all(np.abs(est - TOY_K) < 4 * sig), (est, TOY_K, sig)
    assert "‰/(rad/s)" in first.evidence["summary"]  # the unit the class declares, scaled by its factor
    assert f"{est[0] * 1e3:.3g}" in first.evidence["summary"]
    assert toy(**{k: v for k, v in first.model.items() if k != "effect"}).value.shape == (3,)  # injectable


def test_the_registry_is_filled_by_definition_and_refuses_a_kind_defined_twice():
    from gyrosim.effects import Bias
    from gyrosim.errors import GyrosimError

    before = dict(EFFECTS)

    @dataclass(frozen=True)
    class LoudBias(Bias):  # a variant without a kind of its own: not a new vocabulary entry
        pass

    assert EFFECTS == before and LoudBias.kind == "bias"
    with pytest.raises(GyrosimError, match="defined twice"):
        @dataclass(frozen=True)
        class OtherBias(VectorEffect):
            kind: ClassVar[str] = "bias"
            quantities: ClassVar[dict[str, str]] = {"gyro": "rate"}
    assert EFFECTS == before and EFFECTS["bias"] is Bias
    # derived declarations: a deterministic error-stage gyro effect is a loop candidate, a random one is not
    assert Bias.candidate and not EFFECTS["white_noise"].candidate and EFFECTS["white_noise"].closeloop_reason


def test_build_candidate_raises_the_reason_a_kind_is_no_candidate():
    """build_candidate returns a Candidate or raises Untestable carrying the report's reason (the
    loop's "Not tested" text), never a value to test with isinstance."""
    from calib.closeloop.candidates import Untestable
    from calib.closeloop.catalogue import build_candidate, family_for

    for kind, part in (("white_noise", ""), ("hard_iron", "not an effect of the gyro triad"),
                       ("no_such_effect", "not in the effect vocabulary")):
        with pytest.raises(Untestable) as err:
            build_candidate(kind, None, None)   # refused before the context is read
        assert err.value.kind == kind and part in err.value.reason
        assert err.value.reason == family_for(kind).reason
    assert EFFECTS["misalignment"].axis_rotation and EFFECTS["frame_rotation"].axis_rotation
    assert not EFFECTS["nonorthogonality"].axis_rotation   # symmetric: no rotation part


def test_the_gyro_axes_take_a_found_misalignment_by_its_class_flag():
    """_gyro_axes (the reference-frame note's gyro side) adds a found term whose class turns the axes
    (Misalignment.axis_rotation) from its reported model, and ignores the other found terms."""
    from types import SimpleNamespace

    from calib.closeloop.loop import _gyro_axes
    from calib.closeloop.mag.loop import reference_frame_note

    v = [1e-3, -2e-3, 3e-3, 4e-3, -5e-3, 6e-3]
    mis = EFFECTS["misalignment"](value=v)
    model = {k: (x.tolist() if isinstance(x, np.ndarray) else x) for k, x in mis.to_dict().items()}
    bias = {k: (x.tolist() if isinstance(x, np.ndarray) else x)
            for k, x in EFFECTS["bias"](value=[1e-3, 0, 0]).to_dict().items()}
    res = SimpleNamespace(declared_params={}, found=[SimpleNamespace(effect="bias", model=bias),
                                                     SimpleNamespace(effect="misalignment", model=model)])
    np.testing.assert_array_equal(_gyro_axes(res), mis.affine()[0])
    assert _gyro_axes(SimpleNamespace(declared_params={}, found=res.found[:1])) is None
    m = mis.affine()[0]
    a = 0.5 * np.array([m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1]])
    mag = SimpleNamespace(found=[SimpleNamespace(effect="frame_rotation", params={
        n: {"value": float(-x)} for n, x in zip(("theta_x", "theta_y", "theta_z"), a)})])
    assert "the same rotation seen by both sensors" in reference_frame_note(mag, m)
