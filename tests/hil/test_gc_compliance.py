"""The gravity compensator's compliance C of (8), ug = C tau_g: the figure by hand, and what each
reading leaves of the link error on the emulated DYROS-JET.

The joint is the gear spring K in series with the H54 position servo's static stiffness
k_s = Kpp kv (its velocity integral winds the servo's part out over Ti = 15 s). Linear statics
of a loaded joint under goal theta_d + c tau_g(theta_d), with the servo's integral I(t):

    link error e = c tau_g(theta_d) - tau(theta) / K - (tau(theta) - I) / k_s,
    tau(theta) = tau_g + H e (H = d tau_g / d theta: gravity's stiffness through the posture),
    dI/dt = (tau - I) / Ti  ->  I = tau (1 - x),  x = exp(-t / Ti)  (quasi-static)

so with C = 1/K + 1/k_s, v = (I + C H)^-1 (tau_g / k_s):

    "joint" (c = C):    e(t) = (1 - x) v      (the integral slowly over-compensates)
    "gear"  (c = 1/K):  e(t) = -x v           (the servo's lag, slowly wound out)

The gearbox's Coulomb friction F_c lets a motor rest anywhere within F_c / k_s of that (5 mrad
at the hips, 2.8 at the knees). In double support the chain is statically indeterminate: only
the sagittal joints (hip pitch, knee, ankle pitch) carry the split's torques there.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from controller import GcCompliance, joint_static_compliance
from controller.humanoid import HumanoidLegGravity, LegModel, SupportState
from hil.cli import main
from hil.config import load_config, robot_description_text
from hil.controllers.paper_factory import gc_compliance
from hil.wiring.emulation import emulated_joint_stiffness
from sim_backend.dynamixel.device import H54Device
from sim_backend.humanoid.params import RobotTruthParams, leg_eeprom_overrides
from sim_backend.humanoid.robot import EmulatedRobot
from sim_backend.servo import RAD_PER_PULSE
from tests.sim_backend.test_humanoid_statics import posture

KNEES = (3, 9)
SAGITTAL = (2, 3, 4, 8, 9, 10)
SETTLED_S = 2.0  # the servo's position loop (1/Kpp = 0.1 s) has settled; x = 0.875


def test_compliance_by_hand() -> None:
    """1/K + 1/(Kpp kv) with the H54's figures: 1/2000 + 1/(10 x 78.5) and, at the knees'
    Kpp = 18 (the lab's), 1/2000 + 1/1413; the paper's reading is 1/2000."""
    assert joint_static_compliance(2000.0, 10.0, 78.5) == pytest.approx(0.0005 + 1 / 785)
    assert pytest.approx(0.00177389, abs=1e-8) == 0.0005 + 1 / 785
    testbed = load_config()
    assert gc_compliance(testbed) == pytest.approx([0.00177389], abs=1e-8)
    assert gc_compliance(testbed, GcCompliance.GEAR) == pytest.approx([0.0005])
    jet = load_config(robot="dyros-jet")
    assert jet.controller.gc_compliance == GcCompliance.JOINT
    expected = np.full(12, 0.0005 + 1 / 785)
    expected[list(KNEES)] = 0.0005 + 1 / (18 * 78.5)
    assert gc_compliance(jet) == pytest.approx(expected, rel=1e-12)
    assert gc_compliance(jet.changed("controller", gc_compliance="gear")) == pytest.approx(
        np.full(12, 0.0005)
    )
    # a pasted `hil identify` fragment for one joint changes that joint only
    changed = jet.changed(
        "model",
        joint={
            **jet.model.model_dump()["joint"],
            "L_HipRoll": {"position_gain_per_s": 7.5, "velocity_gain_nms_per_rad": 60.0},
        },
    )
    assert gc_compliance(changed)[1] == pytest.approx(0.0005 + 1 / 450)
    assert gc_compliance(changed)[7] == pytest.approx(expected[7])


def test_the_emulated_joints_by_hand_and_hil_model(capsys: pytest.CaptureFixture[str]) -> None:
    """The emulated knees run Position P Gain 58: Kpp = 10 x 58 / 32 = 18.125 1/s, k_s =
    1422.8 N m/rad, C = 0.0005 + 1/1422.8125; `hil model` prints both sides."""
    jet = load_config(robot="dyros-jet")
    emulated = emulated_joint_stiffness(jet)
    knee = emulated[3]
    assert knee.servo.position_gain_per_s == pytest.approx(18.125)
    assert knee.servo.static_stiffness_nm_per_rad == pytest.approx(1422.8125)
    assert knee.compliance_rad_per_nm == pytest.approx(0.0005 + 1 / 1422.8125)
    assert emulated[1].compliance_rad_per_nm == pytest.approx(0.0005 + 1 / 785)
    assert emulated[1].servo.velocity_integral_time_s == pytest.approx(15.0)
    assert main(["model", "--robot", "dyros-jet", "--json"]) == 0
    record = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    rows = {row["joint"]: row for row in record["joints"]}
    assert record["gc_compliance"] == "joint"
    assert rows["R_KneePitch"]["C joint"] == pytest.approx(0.0005 + 1 / (18 * 78.5))
    assert rows["R_KneePitch"]["emulated C"] == pytest.approx(0.0005 + 1 / 1422.8125)
    assert rows["L_AnkleRoll"]["C gear"] == pytest.approx(0.0005)
    assert main(["model", "--robot", "dyros-jet"]) == 0
    table = capsys.readouterr().out
    assert "L_KneePitch" in table and "0.001208" in table and "0.001203" in table


@pytest.fixture(scope="module")
def jet():
    config = load_config(robot="dyros-jet")
    urdf = robot_description_text(config)
    return config, urdf, LegModel(urdf)


def _stand(urdf: str, angles: np.ndarray, goal: np.ndarray, support: SupportState):
    devices = [H54Device(i + 1, eeprom_overrides=leg_eeprom_overrides()) for i in range(12)]
    robot = EmulatedRobot(urdf, devices, initial_leg_angles_rad=angles, support_feet=support.feet)
    for index, device in enumerate(devices):
        device.set_item("Torque Enable", 1)
        device.set_item("Goal Position", round(goal[index] / RAD_PER_PULSE))
    robot.advance(SETTLED_S)
    in_contact = tuple(side for side in (0, 1) if robot.plant.sole_in_contact(side))
    assert in_contact == support.feet
    return robot


@pytest.mark.parametrize("support", [SupportState.LEFT, SupportState.RIGHT, SupportState.DOUBLE])
def test_joint_compliance_leaves_a_fraction_of_the_gears_error(jet, support) -> None:
    """The stock servo (Ti = 15 s), 2 s after the robot was put down at theta_d: with
    ug = C tau_g the links sit within (1 - x) v + F_c / k_s of theta_d; with the paper's K^-1
    they lag by x v (module docstring). Single support: every joint; double support: the
    sagittal joints, and the pelvis tilt."""
    config, urdf, model = jet
    emulated = emulated_joint_stiffness(config)
    k_s = np.array([j.servo.static_stiffness_nm_per_rad for j in emulated])
    truth = RobotTruthParams()
    ti = truth.servo_params(0).velocity_integral_time_s
    friction = np.array(truth.per_joint("gearbox_coulomb_friction_nm")) / k_s
    x = math.exp(-SETTLED_S / ti)
    angles = posture(model, support)
    gravity = HumanoidLegGravity(model, support)
    tau = gravity.gravity_torque(angles)
    hessian = np.empty((12, 12))
    for j in range(12):
        step = np.zeros(12)
        step[j] = 1e-6
        hessian[:, j] = (
            gravity.gravity_torque(angles + step) - gravity.gravity_torque(angles - step)
        ) / 2e-6
    c_joint = gc_compliance(config)
    v = np.linalg.solve(np.eye(12) + np.diag(c_joint) @ hessian, tau / k_s)

    with_joint = _stand(urdf, angles, angles + c_joint * tau, support)
    with_gear = _stand(
        urdf, angles, angles + gc_compliance(config, GcCompliance.GEAR) * tau, support
    )
    e_joint = with_joint.plant.link_angle_rad - angles
    e_gear = with_gear.plant.link_angle_rad - angles
    rows = list(range(12)) if support is not SupportState.DOUBLE else list(SAGITTAL)
    tolerance = friction[rows] + 1e-3
    assert np.all(np.abs(e_joint[rows] - (1 - x) * v[rows]) <= tolerance), (
        e_joint[rows],
        (1 - x) * v[rows],
    )
    # the servo's lag: the loaded joints (> 20 N m) within 15 % (the sag is not small) and
    # the friction band of -x v
    loaded = [j for j in rows if abs(tau[j]) > 20.0]
    assert loaded
    assert np.all(
        np.abs(e_gear[loaded] + x * v[loaded]) <= 0.15 * x * np.abs(v[loaded]) + tolerance[0]
    ), (e_gear[loaded], -x * v[loaded])
    # C leaves a fraction of the gear's error: (1 - x) / x = 0.14 by the physics
    assert np.linalg.norm(e_joint[rows]) < 0.25 * np.linalg.norm(e_gear[rows])
    assert with_joint.plant.pelvis_tilt_rad < 0.25 * with_gear.plant.pelvis_tilt_rad


def test_a_comparison_runs_gc_with_each_reading_and_builds_each() -> None:
    """The humanoid comparisons run GC with the configuration's reading and once more with the
    paper's K^-1: the choice carries it into the controller's (8) (1/K per joint), its label,
    its run directory and the report's lookup, which tells the two GC runs apart."""
    from hil.controllers.paper_factory import build_controller
    from hil.output.report import RunEntry, find
    from hil.robots.dyros_jet.comparison import humanoid_choices
    from hil.vocabulary import ControllerChoice, ControllerKind

    choices = humanoid_choices(0.2)
    gcs = [c for c in choices if c.kind is ControllerKind.GC]
    assert [c.gc_compliance for c in gcs] == [None, GcCompliance.GEAR]
    gear = gcs[1]
    assert (gear.label, gear.dir_name) == ("gc, gear (8)", "gc-gear")
    with pytest.raises(ValueError, match="pid has no gravity compensator"):
        ControllerChoice(ControllerKind.PID, gc_compliance=GcCompliance.GEAR)
    testbed = load_config()  # one joint: 1/K + 1/(Kpp kv) = 0.00177389, 1/K = 0.0005
    offsets = {}
    for choice in gcs:
        controller = build_controller(testbed, choice, 0.005)
        theta = np.array([0.4])  # a posture where gravity loads the joint
        controller.reset(theta, theta, theta, theta)
        offsets[choice.gc_compliance] = float(controller.step(theta, theta, theta)[0] - 0.4)
    assert abs(offsets[None]) > 1e-4
    assert offsets[None] / offsets[GcCompliance.GEAR] == pytest.approx(
        0.00177389 / 0.0005, rel=1e-5
    )
    entries = [RunEntry("stand", c, None) for c in gcs]  # type: ignore[arg-type]
    assert find(entries, "stand", ControllerKind.GC) is entries[0]
    assert find(entries, "stand", ControllerKind.GC, gc_compliance="gear") is entries[1]
