"""The walking pattern: a plan's trajectories on the control grid, computed once, read per tick.

For a footstep plan and parameters, `WalkingPattern` computes at construction:
  - the timeline (phase per tick) and the ZMP reference (`timeline.py`, `zmp_reference.py`);
  - the CoM by Kajita's preview control on the cart-table (`preview_control.py`), z = zc;
  - the pelvis: CoM plus a constant offset in the pelvis's yaw frame (zero by default: the
    pelvis stands in for the CoM, as in the lab's code), yaw = the mean of the feet's yaws;
  - the feet (ankle-roll frames): planted at ankle_height_m above their footsteps, quintic
    swings (`swing_foot.py`);
  - with a leg geometry, the 12 joint angles by closed-form IK (`leg_ik.py`);
  - with a leg geometry and a whole-robot CoM model (`center_of_mass.py`), the pelvis instead
    solved per tick (Newton's method, warm-started from the previous ticks) so that the
    model's CoM at the IK posture is the planned CoM within com_tolerance_m.
`sample(tick)` then returns views into those arrays: no computation on the 200 Hz path.

Frames: world x forward, y left, z up, ground at z = 0; positions [m], angles [rad].
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from controller.walking.center_of_mass import CenterOfMassModel
from controller.walking.dyros_jet_figures import SOLE_BELOW_ANKLE_M
from controller.walking.footsteps import FootstepPlan, FootstepPlanError, Side
from controller.walking.leg_ik import LegIkError, LegsGeometry, leg_inverse_kinematics
from controller.walking.preview_control import (
    STANDARD_GRAVITY_M_S2,
    CartTableParams,
    CartTableTrajectory,
    PreviewGains,
    PreviewWeights,
    design_preview_controller,
    track_zmp_reference,
)
from controller.walking.swing_foot import SwingFootTrajectory, wrap_angle
from controller.walking.timeline import PhaseSample, SegmentKind, WalkTimeline
from controller.walking.zmp_reference import ZmpReferenceParams, ZmpTransition, zmp_reference


@dataclass(frozen=True)
class WalkingParams:
    """dt_s: control period; com_height_m: the cart-table's zc; preview_horizon_s: Kajita's
    1.6 s by default; swing_height_m: swing apex above the ground (the lab's 2018 value, 0.05);
    ankle_height_m: the ankle axes above the sole (DYROS-JET: 0.105, `dyros_jet_figures`);
    pelvis_offset_from_com_m: pelvis origin minus CoM in the pelvis's yaw frame (the start
    value of the per-tick solve when a CoM model is given); com_tolerance_m and
    com_max_iterations: that solve's tolerance per axis and iteration limit; zmp: smooth
    double-support transitions by default (lower peak error than linear ones, same RMS);
    swing_guard_s: how long the swing foot stays on the ground (unloaded, the ZMP on the
    stance foot) at each end of its single support: it lifts swing_guard_s after the single
    support begins and lands swing_guard_s before it ends (0: the swing fills the single
    support; the lab's code: t_rest_temp = 0.1 s, psh117/dyros_jet walking_controller.cpp
    `getFootTrajectory`, so that a foot that arrives late still lands before the ZMP moves
    onto it); preview_height_m: the cart-table's zc in the preview controller alone (None:
    com_height_m, the CoM's height above the ground the ZMP lies on; the lab's code takes
    the CoM's height in its support foot's frame, the ankle: walking_controller.cpp,
    `updateInitialState`, zc_ = com_support_init_(2)), the planned CoM staying at
    com_height_m."""

    dt_s: float = 0.005
    com_height_m: float = 0.8
    gravity_mps2: float = STANDARD_GRAVITY_M_S2
    preview_horizon_s: float = 1.6
    preview_weights: PreviewWeights = field(default_factory=PreviewWeights)
    zmp: ZmpReferenceParams = field(
        default_factory=lambda: ZmpReferenceParams(transition=ZmpTransition.SMOOTH)
    )
    swing_height_m: float = 0.05
    ankle_height_m: float = SOLE_BELOW_ANKLE_M
    swing_guard_s: float = 0.0
    preview_height_m: float | None = None
    pelvis_offset_from_com_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    com_tolerance_m: float = 1e-7
    com_max_iterations: int = 50

    def __post_init__(self) -> None:
        if not (math.isfinite(self.com_tolerance_m) and self.com_tolerance_m > 0):
            raise ValueError(f"com_tolerance_m must be > 0, got {self.com_tolerance_m}")
        if not (isinstance(self.com_max_iterations, int) and self.com_max_iterations >= 1):
            raise ValueError(
                f"com_max_iterations must be an int >= 1, got {self.com_max_iterations}"
            )
        for name in ("swing_height_m", "ankle_height_m", "swing_guard_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be finite and >= 0, got {value}")
        offset = tuple(float(v) for v in self.pelvis_offset_from_com_m)
        if len(offset) != 3 or not all(math.isfinite(v) for v in offset):
            raise ValueError(f"pelvis_offset_from_com_m must be 3 finite numbers, got {offset}")
        object.__setattr__(self, "pelvis_offset_from_com_m", offset)

    def cart_table(self) -> CartTableParams:
        """The preview controller's cart-table (zc: preview_height_m, else com_height_m)."""
        height = self.com_height_m if self.preview_height_m is None else self.preview_height_m
        return CartTableParams(height, self.gravity_mps2, self.dt_s)


@dataclass(frozen=True)
class WalkingSample:
    """The pattern at one tick. Arrays are read-only views: copy before changing them.

    foot_position_m (2, 3) and foot_yaw_rad (2,): rows left, right (ankle-roll frames).
    joint_angles_rad (12,): left hip yaw..ankle roll, then right; None without a leg geometry.
    """

    tick: int
    time_s: float
    phase: PhaseSample
    com_position_m: np.ndarray
    com_velocity_mps: np.ndarray
    com_acceleration_mps2: np.ndarray
    pelvis_position_m: np.ndarray
    pelvis_yaw_rad: float
    foot_position_m: np.ndarray
    foot_yaw_rad: np.ndarray
    zmp_reference_m: np.ndarray
    joint_angles_rad: np.ndarray | None


def yaw_rotation(yaw_rad: float) -> np.ndarray:
    c, s = math.cos(yaw_rad), math.sin(yaw_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _read_only(array: np.ndarray) -> np.ndarray:
    array.setflags(write=False)
    return array


class WalkingPattern:
    """A plan's walking pattern, precomputed (module docstring). Per-tick arrays (N ticks):

    time_s (N,); zmp_reference_m (N, 2); model_zmp_m (N, 2) (the cart-table's ZMP);
    com_position_m, com_velocity_mps, com_acceleration_mps2 (N, 3); pelvis_position_m (N, 3);
    pelvis_yaw_rad (N,); foot_position_m, foot_velocity_mps, foot_acceleration_mps2 (N, 2, 3);
    foot_yaw_rad (N, 2); joint_angles_rad (N, 12) or None; model_com_m (N, 3), the CoM model's
    CoM at the solved posture, or None without a CoM model.
    """

    def __init__(
        self,
        plan: FootstepPlan,
        params: WalkingParams | None = None,
        legs: LegsGeometry | None = None,
        com_model: CenterOfMassModel | None = None,
    ) -> None:
        if com_model is not None and legs is None:
            raise ValueError("a CoM model needs the leg geometry (the pelvis is solved by IK)")
        params = WalkingParams() if params is None else params
        self.plan = plan
        self.params = params
        self.legs = legs
        if plan.timing.initial_rest_s < params.preview_horizon_s - 1e-12:
            raise FootstepPlanError(
                f"initial_rest_s = {plan.timing.initial_rest_s} s is shorter than the preview "
                f"horizon ({params.preview_horizon_s} s): the preview would see the walk start "
                f"before the pattern does, and the CoM would start with an error of centimetres"
            )
        self.timeline = WalkTimeline(plan, params.dt_s)
        n = self.timeline.n_ticks
        self.time_s = _read_only(self.timeline.time_s())
        self.zmp_reference_m = _read_only(zmp_reference(self.timeline, params.zmp))
        self.preview_gains: PreviewGains = design_preview_controller(
            params.cart_table(), params.preview_weights, params.preview_horizon_s
        )
        cart: CartTableTrajectory = track_zmp_reference(self.preview_gains, self.zmp_reference_m)
        self.model_zmp_m = _read_only(cart.zmp_m)

        self.com_position_m = np.zeros((n, 3))
        self.com_position_m[:, :2] = cart.position_m
        self.com_position_m[:, 2] = params.com_height_m
        self.com_velocity_mps = np.zeros((n, 3))
        self.com_velocity_mps[:, :2] = cart.velocity_mps
        self.com_acceleration_mps2 = np.zeros((n, 3))
        self.com_acceleration_mps2[:, :2] = cart.acceleration_mps2

        self._build_feet()
        left_yaw, right_yaw = self.foot_yaw_rad[:, 0], self.foot_yaw_rad[:, 1]
        wrapped = wrap_angle(right_yaw - left_yaw)
        self.pelvis_yaw_rad = _read_only(left_yaw + 0.5 * wrapped)
        offset = np.array(params.pelvis_offset_from_com_m)
        c, s = np.cos(self.pelvis_yaw_rad), np.sin(self.pelvis_yaw_rad)
        self.pelvis_position_m = self.com_position_m.copy()
        self.pelvis_position_m[:, 0] += c * offset[0] - s * offset[1]
        self.pelvis_position_m[:, 1] += s * offset[0] + c * offset[1]
        self.pelvis_position_m[:, 2] += offset[2]
        self.joint_angles_rad: np.ndarray | None = None
        self.model_com_m: np.ndarray | None = None
        if legs is not None:
            self.joint_angles_rad = np.empty((n, 12))
            if com_model is None:
                self._solve_ik(legs)
            else:
                self.model_com_m = np.empty((n, 3))
                self._solve_ik_on_com(legs, com_model)
        for array in (
            self.com_position_m,
            self.com_velocity_mps,
            self.com_acceleration_mps2,
            self.pelvis_position_m,
            self.joint_angles_rad,
            self.model_com_m,
        ):
            if array is not None:
                _read_only(array)

    def __len__(self) -> int:
        return self.timeline.n_ticks

    @property
    def n_ticks(self) -> int:
        return self.timeline.n_ticks

    @property
    def dt_s(self) -> float:
        return self.params.dt_s

    def _build_feet(self) -> None:
        n = self.timeline.n_ticks
        pose = np.empty((n, 2, 4))  # x, y, z above ground, yaw
        vel = np.zeros((n, 2, 4))
        acc = np.zeros((n, 2, 4))
        placed = {Side.LEFT: self.plan.initial_left, Side.RIGHT: self.plan.initial_right}
        for seg in self.timeline.segments:
            rows = slice(seg.start_tick, seg.end_tick)
            swinging = seg.landing_side if seg.kind is SegmentKind.SINGLE_SUPPORT else None
            for side in Side:
                start = placed[side]
                if side is swinging:
                    target = self.plan.footsteps[seg.footstep_index]
                    guard = self.params.swing_guard_s
                    airborne = seg.n_ticks * self.dt_s - 2.0 * guard
                    if airborne <= 0.0:
                        raise FootstepPlanError(
                            f"swing_guard_s = {guard} s leaves no swing in a single support of "
                            f"{seg.n_ticks * self.dt_s:.3f} s"
                        )
                    swing = SwingFootTrajectory(
                        (start.x_m, start.y_m),
                        (target.x_m, target.y_m),
                        start.yaw_rad,
                        target.yaw_rad,
                        self.params.swing_height_m,
                        airborne,
                    )
                    t = np.arange(seg.n_ticks) * self.dt_s - guard  # held at both ends
                    pose[rows, side.index], vel[rows, side.index], acc[rows, side.index] = (
                        swing.evaluate(t)
                    )
                    placed[side] = target  # touches down at the end of this segment
                else:
                    pose[rows, side.index] = (start.x_m, start.y_m, 0.0, start.yaw_rad)
        pose[:, :, 2] += self.params.ankle_height_m
        pose[:, :, 3] = wrap_angle(pose[:, :, 3])
        self.foot_position_m = _read_only(np.ascontiguousarray(pose[:, :, :3]))
        self.foot_yaw_rad = _read_only(np.ascontiguousarray(pose[:, :, 3]))
        self.foot_velocity_mps = _read_only(np.ascontiguousarray(vel[:, :, :3]))
        self.foot_acceleration_mps2 = _read_only(np.ascontiguousarray(acc[:, :, :3]))

    def _legs_ik(
        self, legs: LegsGeometry, k: int, pelvis_position: np.ndarray, pelvis_rotation: np.ndarray
    ) -> np.ndarray:
        angles = np.empty(12)
        for side in Side:
            try:
                angles[6 * side.index : 6 * side.index + 6] = leg_inverse_kinematics(
                    legs.leg(side),
                    pelvis_position,
                    pelvis_rotation,
                    self.foot_position_m[k, side.index],
                    yaw_rotation(self.foot_yaw_rad[k, side.index]),
                )
            except LegIkError as error:
                raise LegIkError(
                    f"tick {k} (t = {k * self.dt_s:.3f} s), {side.value} leg: {error}"
                ) from error
        return angles

    def _solve_ik(self, legs: LegsGeometry) -> None:
        for k in range(self.n_ticks):
            self.joint_angles_rad[k] = self._legs_ik(
                legs, k, self.pelvis_position_m[k], yaw_rotation(self.pelvis_yaw_rad[k])
            )

    def _solve_ik_on_com(self, legs: LegsGeometry, com_model: CenterOfMassModel) -> None:
        """Per tick, Newton's method on the pelvis position p for CoM(p) = CoM reference: the
        IK re-solves the legs for each p (feet fixed), J = dCoM/dp is estimated once by finite
        differences at the first tick (it is close to the identity scaled by the share of the
        mass that moves with the pelvis, and changes little over a walk), then
        p += J^-1 (CoM reference - CoM(p)) until the residual is under com_tolerance_m. The
        start value is extrapolated from the previous two ticks' pelvis - CoM offsets."""
        tolerance, max_iterations = self.params.com_tolerance_m, self.params.com_max_iterations

        def model_com(k: int, pelvis: np.ndarray, rotation: np.ndarray):
            angles = self._legs_ik(legs, k, pelvis, rotation)
            return angles, np.asarray(com_model(pelvis, rotation, angles), dtype=float)

        rotation = yaw_rotation(self.pelvis_yaw_rad[0])
        start = self.pelvis_position_m[0].copy()
        _, com_start = model_com(0, start, rotation)
        step_m = 1e-4
        jacobian = np.empty((3, 3))
        for axis in range(3):
            moved = start.copy()
            moved[axis] += step_m
            jacobian[:, axis] = (model_com(0, moved, rotation)[1] - com_start) / step_m
        inverse = np.linalg.inv(jacobian)

        offsets = [start - self.com_position_m[0]] * 2
        for k in range(self.n_ticks):
            rotation = yaw_rotation(self.pelvis_yaw_rad[k])
            target = self.com_position_m[k]
            pelvis = target + 2.0 * offsets[-1] - offsets[-2]
            for _ in range(max_iterations):
                angles, com = model_com(k, pelvis, rotation)
                residual = target - com
                if np.abs(residual).max() < tolerance:
                    break
                pelvis = pelvis + inverse @ residual
            else:
                raise LegIkError(
                    f"tick {k}: the pelvis solve for the planned CoM did not converge in "
                    f"{max_iterations} iterations (residual {np.abs(residual).max():.2e} m)"
                )
            self.pelvis_position_m[k] = pelvis
            self.joint_angles_rad[k] = angles
            self.model_com_m[k] = com
            offsets = [offsets[-1], pelvis - target]

    def leg_angles_with_pelvis(self, tick: int, pelvis_position_m: np.ndarray) -> np.ndarray:
        """The 12 joint angles at `tick` with the pelvis moved to `pelvis_position_m` (its yaw
        and the feet as planned): closed-form IK, for a pelvis corrected on line (the lab's CoM
        feedback, `controller.walking.lab_terms`). Raises LegIkError out of the legs' reach."""
        if self.legs is None:
            raise ValueError("the pattern has no leg geometry: no joint angles")
        if not 0 <= tick < self.timeline.n_ticks:
            raise IndexError(f"tick {tick} outside the pattern's 0..{self.timeline.n_ticks - 1}")
        rotation = yaw_rotation(self.pelvis_yaw_rad[tick])
        return self._legs_ik(self.legs, tick, np.asarray(pelvis_position_m, dtype=float), rotation)

    def sample(self, tick: int) -> WalkingSample:
        """The pattern at `tick` (0 <= tick < n_ticks)."""
        if not 0 <= tick < self.timeline.n_ticks:
            raise IndexError(f"tick {tick} outside the pattern's 0..{self.timeline.n_ticks - 1}")
        return WalkingSample(
            tick=tick,
            time_s=tick * self.params.dt_s,
            phase=self.timeline.phase(tick),
            com_position_m=self.com_position_m[tick],
            com_velocity_mps=self.com_velocity_mps[tick],
            com_acceleration_mps2=self.com_acceleration_mps2[tick],
            pelvis_position_m=self.pelvis_position_m[tick],
            pelvis_yaw_rad=float(self.pelvis_yaw_rad[tick]),
            foot_position_m=self.foot_position_m[tick],
            foot_yaw_rad=self.foot_yaw_rad[tick],
            zmp_reference_m=self.zmp_reference_m[tick],
            joint_angles_rad=None if self.joint_angles_rad is None else self.joint_angles_rad[tick],
        )

    def generator_zmp_error_m(self) -> np.ndarray:
        """The cart-table's ZMP minus the reference, (N, 2) [m]: the generator's own error."""
        return self.model_zmp_m - self.zmp_reference_m
