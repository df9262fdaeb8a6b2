"""The H54 firmwares' measurement noise for a bank of n joints (`H54FirmwareBank`).

Present Current (and, for the testbed, Present Velocity) carry zero-mean Gaussian noise
(`H54ServoParams.current_noise_a`, `velocity_noise_rad_s`), drawn from one seeded Generator in
joint order: per physics step, for each joint, its current's draw then its velocity's, for every
rms > 0. The draws come a block of standard normals at a time (`NormalStream`): the same values
as one `normal(0, rms)` call per draw.
"""

from __future__ import annotations

import numpy as np

from sim_backend.normal_stream import NormalStream


class ServoNoise:
    """See the module docstring. current_rms / velocity_rms: per joint [A], [rad/s]; rng:
    None for no noise at all."""

    def __init__(
        self, current_rms: np.ndarray, velocity_rms: np.ndarray, rng: np.random.Generator | None
    ) -> None:
        n = len(current_rms)
        self._current_rms = current_rms
        self._velocity_rms = velocity_rms
        # the draws of one step, in stream order: (joint, is_velocity)
        slots = [
            (j, kind)
            for j in range(n)
            for kind, rms in ((False, current_rms[j]), (True, velocity_rms[j]))
            if rms > 0
        ]
        self._stream = NormalStream(rng) if rng is not None and slots else None
        self._draws_per_step = len(slots)
        self._current_slots = np.array([i for i, (_, v) in enumerate(slots) if not v], int)
        self._current_joints = np.array([j for j, v in slots if not v], int)
        self._velocity_slots = np.array([i for i, (_, v) in enumerate(slots) if v], int)
        self._velocity_joints = np.array([j for j, v in slots if v], int)
        self._current = np.zeros(n)
        self._velocity = np.zeros(n)
        self.velocity_noisy = len(self._velocity_joints) > 0
        # the usual draw: the current's of every joint, in joint order
        self._every_current = (
            self._current_slots.tolist() == list(range(n)) == self._current_joints.tolist()
        )

    def draw(self) -> tuple[np.ndarray, np.ndarray]:
        """This step's noise of every joint (current, velocity): buffers, valid until the next
        call."""
        current, velocity = self._current, self._velocity
        if self._stream is None:
            return current, velocity
        draws = self._stream.take(self._draws_per_step)
        if self._every_current and not self.velocity_noisy:
            np.multiply(draws, self._current_rms, out=current)
            return current, velocity
        joints, slots = self._current_joints, self._current_slots
        current[joints] = draws[slots] * self._current_rms[joints]
        joints, slots = self._velocity_joints, self._velocity_slots
        velocity[joints] = draws[slots] * self._velocity_rms[joints]
        return current, velocity

    def draw_joint(self, joint: int) -> tuple[float, float]:
        """One joint's noise (current, then velocity), drawn as a step draws it."""
        noise = [0.0, 0.0]
        if self._stream is not None:
            for kind, rms in enumerate((self._current_rms, self._velocity_rms)):
                if rms[joint] > 0:
                    noise[kind] = self._stream.next() * rms[joint].item()
        return noise[0], noise[1]
