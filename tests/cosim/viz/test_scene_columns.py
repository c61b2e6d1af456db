"""The scene's per-row columns written out by hand (cosim.viz.scene) against the libraries
they replace for speed: scipy's rotations and rerun's own strip conversion."""

from __future__ import annotations

import numpy as np
import rerun as rr
from scipy.spatial.transform import Rotation

from cosim.viz.scene import euler_to_quaternions, pitch_quaternions, strips_of_segments


def test_pose_quaternions_are_scipys_zyx_euler_rotation_with_its_sign():
    rng = np.random.default_rng(7)
    roll, pitch, yaw = rng.uniform(-np.pi, np.pi, (3, 500))
    pitch = pitch / 2.0  # |pitch| < pi/2: the Euler angles are unique
    expected = Rotation.from_euler("ZYX", np.column_stack([yaw, pitch, roll])).as_quat()
    np.testing.assert_allclose(euler_to_quaternions(roll, pitch, yaw), expected, atol=1e-15)


def test_fin_quaternions_turn_about_the_body_y_axis():
    angles = np.linspace(-0.5, 0.5, 11)
    expected = Rotation.from_rotvec(np.outer(angles, [0.0, 1.0, 0.0])).as_quat()
    np.testing.assert_allclose(pitch_quaternions(angles), expected, atol=1e-15)


def test_segments_become_the_arrow_array_rerun_would_build():
    segments = np.random.default_rng(3).normal(size=(40, 2, 3))
    ours = strips_of_segments(segments)
    assert ours.equals(rr.components.LineStrip3DBatch(segments).as_arrow_array())
    assert len(strips_of_segments(segments[:0])) == 0
