"""Delta URR legs (Fig. 5.27) and Grübler's mobility formula (5.16)."""

from __future__ import annotations

import numpy as np
import pytest

from redundik.errors import MechanismError
from redundik.parallel import DeltaRobot, JointGroup, UPRPlatform, grubler, leg_frame, planar_link, urr_angles


@pytest.mark.parametrize("length", [0.3, 1.0, 1.5, 1.69])
def test_urr_angles_reach_the_upr_length_with_the_knee_outward(length: float) -> None:
    a1, a2 = 0.8, 0.9
    t1, t2 = urr_angles(length, a1, a2)
    tip = (planar_link(t1, a1) @ planar_link(t2, a2))[:3, 3]
    np.testing.assert_allclose(tip, [length, 0.0, 0.0], atol=1e-14)
    assert -np.pi < t2 < 0 < t1
    knee = np.cos(t2 + np.pi)  # law of cosines on ∠A_a = θ2 + 180°
    assert knee == pytest.approx((a1**2 + a2**2 - length**2) / (2 * a1 * a2), abs=1e-14)


@pytest.mark.parametrize("length", [0.05, 1.75, 3.0, float("nan")])
def test_urr_out_of_reach(length: float) -> None:
    with pytest.raises(MechanismError, match="out of reach"):
        urr_angles(length, 0.8, 0.9)


def test_leg_frame_requires_orthogonal_axis() -> None:
    H = leg_frame([0.0, 0.0, 2.0], [1.0, 0.0, 0.0], [1.0, 2.0, 3.0])
    np.testing.assert_allclose(H[:3, :3].T @ H[:3, :3], np.eye(3), atol=1e-15)
    assert np.linalg.det(H[:3, :3]) == pytest.approx(1.0)
    np.testing.assert_allclose(H[:3, 3], [1.0, 2.0, 3.0])
    with pytest.raises(MechanismError, match="not perpendicular"):
        leg_frame([0.0, 0.0, 2.0], [1.0, 0.0, 1.0], [0.0, 0.0, 0.0])


def test_delta_ik_tips_meet_the_top_joints() -> None:
    plat = UPRPlatform.book_layout("equilateral", 1.0, 0.4, d4=0.0)
    delta = DeltaRobot(plat, 0.8, 0.9)
    top = np.array([0.05, 0.02, 1.0])
    legs = delta.inverse_kinematics(top)
    joints = legs.o3 + plat.top_points @ legs.R03.T
    np.testing.assert_allclose(legs.tips, joints, atol=1e-12)
    for i in range(3):
        np.testing.assert_allclose(np.linalg.norm(legs.knees[i] - plat.base_points[i]), 0.8, atol=1e-12)
        np.testing.assert_allclose(np.linalg.norm(legs.tips[i] - legs.knees[i]), 0.9, atol=1e-12)
        # knee outward: further from the base centre axis than its base joint
        assert np.linalg.norm(legs.knees[i, :2]) > np.linalg.norm(plat.base_points[i, :2])
        # the leg plane is normal to the revolute axis
        axis = legs.frames[i, :3, 2]
        assert (legs.knees[i] - plat.base_points[i]) @ axis == pytest.approx(0.0, abs=1e-12)
    with pytest.raises(MechanismError, match="out of reach"):
        delta.inverse_kinematics([0.0, 0.0, 3.0])


# ---------------------------------------------------------------------------------------------- mobility
def test_planar_hybrid_fig_5_13() -> None:
    assert grubler(3, 7, [("R", 9)]).m == 3


def test_stewart_platform() -> None:
    mob = grubler(6, 13, [("U", 6), ("P", 6), ("S", 6)])
    assert (mob.m, mob.F, mob.joints, mob.passive) == (6, 36, 18, 30)
    # the chapter's S/U naming is the reverse of common usage; the total does not change
    assert grubler(6, 13, [("hooke", 6), ("P", 6), ("ball", 6)]).m == 6


@pytest.mark.parametrize("legs", [[("S", 6), ("P", 3)], [("U", 3), ("P", 3), ("R", 3)], [("U", 3), ("R", 6)]])
def test_three_leg_platforms(legs: list) -> None:
    # Fig. 5.23: SPS, UPR and the Delta URR, l = 7 (2 per leg + top), n = 9
    mob = grubler(6, 7, legs)
    assert (mob.m, mob.F) == (3, 15)


def test_serial_chain_has_no_passive_axes() -> None:
    mob = grubler(6, 6, [1] * 6)
    assert mob.m == mob.F == 6 and mob.passive == 0


@pytest.mark.parametrize(("k", "m"), [(3, 12), (6, 18)])
def test_exercise5_ball_cylinder_ball_platform(k: int, m: int) -> None:
    # Fig. 5.34 (right): ball joints (3 axes) at both discs, spinning pistons (cylindrical, 2 axes);
    # the figure's leg count is lost, so k is a parameter: m = 6 + 2k (each leg adds two idle spins)
    assert grubler(6, 2 * k + 1, [("ball", 2 * k), ("C", k)]).m == m


def test_exercise4_planar_three_legs_assumed_rpr() -> None:
    # Fig. 5.33 is lost; read as a planar 3-RPR: l = 7, n = 9 one-axis joints
    assert grubler(3, 7, [("R", 6), ("P", 3)]).m == 3


def test_mobility_errors() -> None:
    with pytest.raises(MechanismError, match="D must be 3"):
        grubler(4, 1, [])
    with pytest.raises(MechanismError, match="unknown joint type 'Q'"):
        grubler(6, 1, [("Q", 1)])
    with pytest.raises(MechanismError, match="1 <= dof <= 3"):
        grubler(3, 1, [JointGroup("custom", 1, 4)])
