"""The accelerometer from a Ferraris session's six box-face poses (:mod:`calib.session.six_poses`)."""

from __future__ import annotations

import numpy as np
import pytest

from gyrosim.rotations import skew

from calib.inputs.errors import TurnsError
from calib.session.model import m_matrix
from calib.session.six_poses import POSES, SixPoses, six_pose_accelerometer

G = 9.81


def _session(rng, b, s, g, phi_rad, noise_m_s2=0.0, n=200):
    """Readings of six poses (n samples each) of an accelerometer f̃ = M f + b whose box is turned by φ against its
    axes (U = expm([φ×]), from Rodrigues), and the section list."""
    th = np.linalg.norm(phi_rad)
    k = skew(phi_rad / th)
    u = np.eye(3) + np.sin(th) * k + (1 - np.cos(th)) * k @ k
    m = m_matrix(s, g)
    acc, segments = [], {}
    for axis, (up, down) in enumerate(POSES):
        for name, sign in ((up, 1.0), (down, -1.0)):
            f = m @ (u @ (sign * G * np.eye(3)[axis])) + b
            segments[name] = {"start": len(acc) * n, "end": (len(acc) + 1) * n}
            acc.append(f + noise_m_s2 * rng.standard_normal((n, 3)))
    return np.vstack(acc), segments, u


def test_recovers_the_symmetric_model_and_the_box_rotation():
    """Noise-free poses give b, S, G exactly (the polar decomposition is exact) and the box's rotation to its
    small-angle approximation (sin θ for θ = 0.9°: 4e-5 relative)."""
    rng = np.random.default_rng(1)
    b, s, g = np.array([0.5, -0.6, 0.4]), np.array([-0.003, 0.003, 0.024]), np.array([0.002, 0.003, -0.003])
    phi = np.radians([0.1, -0.6, 0.65])
    acc, segments, _ = _session(rng, b, s, g, phi)
    got = six_pose_accelerometer(acc, segments, G)
    np.testing.assert_allclose(got.bias_m_s2, b, atol=1e-12)
    np.testing.assert_allclose(got.scale_factor, s, atol=1e-12)
    np.testing.assert_allclose(got.nonorthogonality, g, atol=1e-12)
    np.testing.assert_allclose(np.radians(got.box_rotation_deg), phi, rtol=1e-4)
    assert SixPoses.from_dict(got.to_dict()).to_dict() == got.to_dict()


def test_noise_enters_as_the_pose_means():
    """White noise σ on n samples per pose: each parameter's error is of order σ/√n (bias) and σ/(g√n) (S, G);
    5 of those bounds them at any seed."""
    rng = np.random.default_rng(2)
    sigma, n = 0.05, 200
    b, s, g = np.zeros(3), np.array([0.01, -0.01, 0.0]), np.array([0.0, 0.005, 0.0])
    acc, segments, _ = _session(rng, b, s, g, np.radians([0.2, 0.2, 0.2]), sigma, n)
    got = six_pose_accelerometer(acc, segments, G)
    assert np.all(np.abs(got.bias_m_s2 - b) < 5 * sigma / np.sqrt(n))
    assert np.all(np.abs(got.scale_factor - s) < 5 * sigma / (G * np.sqrt(n)))
    assert np.all(np.abs(got.nonorthogonality - g) < 5 * sigma / (G * np.sqrt(n)))


def test_a_missing_pose_is_named():
    acc, segments, _ = _session(np.random.default_rng(3), np.zeros(3), np.zeros(3), np.zeros(3), np.ones(3) * 1e-3)
    del segments["y_a"]
    with pytest.raises(TurnsError, match="y_a"):
        six_pose_accelerometer(acc, segments, G)
    segments["y_a"] = {"start": 0, "end": acc.shape[0] + 5}
    with pytest.raises(TurnsError, match="outside"):
        six_pose_accelerometer(acc, segments, G)


def test_the_stated_sigma_is_the_scatter_over_draws():
    """``protocol_accelerometer``'s σ (the pose means' noise carried through the equations) against the scatter of
    the estimate over 200 noise draws: each parameter's RMS of error/σ within 0.8–1.25 (the RMS of 200 unit normals
    has a 1σ of 1/√400 = 5 %, so ±20 % is four of those) — an honest σ, neither the 3× too small of a per-sample
    count at 100 Hz nor padded."""
    from calib.session.six_poses import protocol_accelerometer

    b, s, g = np.array([0.5, -0.6, 0.4]), np.array([-0.003, 0.003, 0.024]), np.array([0.002, 0.003, -0.003])
    z = []
    for seed in range(200):
        acc, segments, _ = _session(np.random.default_rng(100 + seed), b, s, g, np.radians([0.1, -0.6, 0.65]),
                                    0.02, 300)
        t = np.arange(acc.shape[0]) / 100.0
        poses = [(name, t[seg["start"]], t[seg["end"] - 1]) for name, seg in segments.items()]
        got, sigma = protocol_accelerometer(acc, t, poses, G)
        z.append((got.theta() - np.concatenate([b, s, g])) / sigma)
    rms = np.sqrt(np.mean(np.square(z), axis=0))
    assert np.all((rms > 0.8) & (rms < 1.25)), rms
