"""The legs' solver: Levenberg-Marquardt on a block Jacobian, each joint's step accepted on its
own cost (hil/twin/legs.py's module docstring says why), and the whole-robot replays it runs.

    Replays         the suspended (or standing) runs replayed on figure sets, `workers` at a
                    time or on Ray (hil/twin/executor.py)
    Rows, Problem   which samples a cost is taken over; which figures of which joints a
                    problem fits, weighted how
    jacobian        the residual and, per figure, the residual with it moved on every joint
                    that fits it (one replay a figure, not one a joint and figure)
    normal_equations  J^T J and J^T r from those blocks (a joint's rows see its own columns
                    and the mass scale's)
    solve           the iterations, a damping per joint
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from hil.config import Config, ConfigError
from hil.twin.executor import ReplayExecutor, install_runs, installed
from hil.twin.figures import Scale
from hil.twin.fit import CHANNELS
from hil.twin.legs_figures import MASS_SCALE, LegFigures, figure, legs_twin_config
from hil.twin.replay import Reading, replay_goals
from hil.twin.runs import RecordedRun

FD_STEP = 1e-3  # the Jacobian's step in fit coordinates (0.1 % of a logarithmic figure)
DAMPING_START = 1e-3  # Levenberg-Marquardt's damping at the start (relative to J^T J's diagonal)
MAX_STEP = 0.5  # the largest change of a figure an iteration, in fit coordinates


# ------------------------------------------------------------------------------ the residual


def replay_all(figures: LegFigures) -> list[np.ndarray] | None:
    """Per run, (ticks, channels, joints) replayed - recorded (NaN zeroed); None where the
    figures make no emulator."""
    try:
        runs, base = installed()
        config = legs_twin_config(base, figures)
        out = []
        for run in runs:
            replayed = replay_goals(config, run, Reading.PLANT)
            if replayed.unstable:
                return None
            block = np.stack(
                [replayed.signal(c) - run.signal(c) for c in CHANNELS], axis=1
            )  # (ticks, channels, joints)
            out.append(np.nan_to_num(block, nan=0.0))
        return out
    except (ValueError, ConfigError):
        return None


class Replays:
    """Replays of many figure sets, `workers` at a time (forks of this process, or Ray tasks)."""

    def __init__(
        self, runs: list[RecordedRun], base: Config, workers: int, ray: str | None = None
    ) -> None:
        self.executor: ReplayExecutor[LegFigures, list[np.ndarray] | None] = ReplayExecutor(
            replay_all, install_runs, (runs, base), workers, ray
        )

    def many(self, sets: list[LegFigures]) -> list[list[np.ndarray] | None]:
        return self.executor.many(sets)

    def close(self) -> None:
        self.executor.close()


@dataclass(frozen=True)
class Rows:
    """Which samples of each run a cost is taken over: per run, a (ticks,) mask."""

    masks: tuple[np.ndarray, ...]


def joint_costs(blocks: list[np.ndarray], rows: Rows, weights: np.ndarray) -> np.ndarray:
    """(joints,) each joint's weighted sum of squares over the rows."""
    total = np.zeros(weights.shape[1])
    for block, mask in zip(blocks, rows.masks, strict=True):
        weighted = block[mask] * weights[None, :, :]
        total += np.sum(weighted**2, axis=(0, 1))
    return total


def joint_residuals(
    blocks: list[np.ndarray], rows: Rows, weights: np.ndarray, joint: int
) -> list[np.ndarray]:
    """Per run, (rows, channels) joint `joint`'s weighted residual."""
    return [
        block[mask][:, :, joint] * weights[None, :, joint]
        for block, mask in zip(blocks, rows.masks, strict=True)
    ]


# ------------------------------------------------------------------------------ coordinates


def moved_figures(start: LegFigures, key: str, joints: Sequence[int], x: float) -> LegFigures:
    """`start` with figure `key` moved by x fit coordinates on `joints` (mass_scale: joints
    ignored)."""
    out = start.copy()
    f = figure(key)
    if key == MASS_SCALE.key:
        out.mass_scale = start.mass_scale * math.exp(x)
        return out
    for j in joints:
        if f.scale is Scale.LOG:
            out.joints[key][j] = start.joints[key][j] * math.exp(x)
        else:
            out.joints[key][j] = max(start.joints[key][j] + f.step * x, f.lower)
    return out


def _clip_step(key: str, value: float, dx: float) -> float:
    """A step in fit coordinates kept within MAX_STEP (a logarithmic figure changes by at most
    x1.65 an iteration: a stiffness or damping twenty times off makes MuJoCo's integration
    unstable) and above a linear figure's lower bound."""
    f = figure(key)
    dx = float(np.clip(dx, -MAX_STEP, MAX_STEP))
    if f.scale is Scale.LINEAR and math.isfinite(f.lower):
        return max(dx, (f.lower - value) / f.step)
    return dx


# ------------------------------------------------------------------------------ the solver


@dataclass
class Problem:
    """One Levenberg-Marquardt problem: which figures of which joints, on which rows."""

    keys: dict[int, tuple[str, ...]]  # per joint, its fitted figures
    with_mass: bool
    rows: Rows
    weights: np.ndarray  # (channels, joints)

    @property
    def groups(self) -> list[str]:
        """The figures perturbed together (each on every joint that fits it)."""
        seen: list[str] = []
        for keys in self.keys.values():
            seen += [k for k in keys if k not in seen]
        return seen


def jacobian(
    replays: Replays, problem: Problem, at: LegFigures
) -> tuple[list[np.ndarray] | None, dict[str, list[np.ndarray] | None]]:
    """The residual at `at` and, per figure group, the residual with it moved by FD_STEP."""
    groups = problem.groups + ([MASS_SCALE.key] if problem.with_mass else [])
    sets = [at] + [
        moved_figures(at, key, [j for j, keys in problem.keys.items() if key in keys], FD_STEP)
        for key in groups
    ]
    results = replays.many(sets)
    return results[0], dict(zip(groups, results[1:], strict=True))


def normal_equations(
    problem: Problem,
    base: list[np.ndarray],
    moved: dict[str, list[np.ndarray] | None],
) -> tuple[list[tuple[int, str]], np.ndarray, np.ndarray, dict[int, np.ndarray]]:
    """(columns, J^T J, J^T r, per joint its (rows, channels, own columns) block)."""
    columns: list[tuple[int, str]] = [(j, k) for j, keys in problem.keys.items() for k in keys]
    if problem.with_mass:
        columns.append((-1, MASS_SCALE.key))
    index = {c: i for i, c in enumerate(columns)}
    n = len(columns)
    jtj, jtr = np.zeros((n, n)), np.zeros(n)
    blocks: dict[int, np.ndarray] = {}
    mass_cols: dict[int, np.ndarray] = {}
    for joint, keys in problem.keys.items():
        r = np.concatenate(joint_residuals(base, problem.rows, problem.weights, joint))
        cols = []
        for key in keys:
            other = moved[key]
            if other is None:  # a step out of the emulator's reach: no slope seen
                cols.append(np.zeros_like(r))
                continue
            moved_r = np.concatenate(joint_residuals(other, problem.rows, problem.weights, joint))
            cols.append((moved_r - r) / FD_STEP)
        block = np.stack(cols, axis=-1)  # (rows, channels, own)
        blocks[joint] = block
        flat = block.reshape(-1, len(keys))
        ids = [index[(joint, k)] for k in keys]
        jtj[np.ix_(ids, ids)] += flat.T @ flat
        jtr[ids] += flat.T @ r.ravel()
        if problem.with_mass and moved[MASS_SCALE.key] is not None:
            other = moved[MASS_SCALE.key]
            assert other is not None
            moved_r = np.concatenate(joint_residuals(other, problem.rows, problem.weights, joint))
            g = ((moved_r - r) / FD_STEP).ravel()
            mass_cols[joint] = g
            m = index[(-1, MASS_SCALE.key)]
            jtj[ids, m] += flat.T @ g
            jtj[m, ids] += flat.T @ g
            jtj[m, m] += g @ g
            jtr[m] += g @ r.ravel()
    return columns, jtj, jtr, blocks


def _step(
    columns: list[tuple[int, str]],
    jtj: np.ndarray,
    jtr: np.ndarray,
    damping: dict[int, float],
    at: LegFigures,
) -> LegFigures:
    """The damped Gauss-Newton step from `at` (each joint's damping on its own columns)."""
    diagonal = np.diag(jtj).copy()
    scale = np.where(diagonal > 0, diagonal, 1.0)
    lam = np.array([damping[j] for j, _ in columns])
    dx = np.linalg.lstsq(jtj + np.diag(lam * scale), -jtr, rcond=None)[0]
    out = at.copy()
    for (joint, key), step in zip(columns, dx, strict=True):
        if joint < 0:
            out = moved_figures(out, key, [], _clip_step(key, out.mass_scale, float(step)))
        else:
            value = float(out.joints[key][joint])
            out = moved_figures(out, key, [joint], _clip_step(key, value, float(step)))
    return out


def solve(
    replays: Replays,
    problem: Problem,
    start: LegFigures,
    iterations: int,
    tolerance: float,
    say: Callable[[str], None],
) -> tuple[LegFigures, bool, int]:
    """Levenberg-Marquardt with per-joint acceptance (module docstring): (figures, converged,
    iterations used)."""
    at = start
    damping = {j: DAMPING_START for j in problem.keys} | {-1: DAMPING_START}
    converged = False
    done = 0
    linearised = None  # the residual, cost and normal equations at `at`, while it stays
    for done in range(1, iterations + 1):
        if linearised is None:
            base, moved = jacobian(replays, problem, at)
            if base is None:
                raise ValueError("the start of the fit makes no emulator")
            cost = joint_costs(base, problem.rows, problem.weights)
            columns, jtj, jtr, _ = normal_equations(problem, base, moved)
            linearised = (cost, columns, jtj, jtr)
        cost, columns, jtj, jtr = linearised
        linearised_mass = at.mass_scale
        trial_at = _step(columns, jtj, jtr, damping, at)
        trial = replays.many([trial_at])[0]
        if trial is None:  # a step MuJoCo cannot integrate: shorter ones from the same point
            for j in damping:
                damping[j] *= 10.0
            continue
        trial_cost = joint_costs(trial, problem.rows, problem.weights)
        accepted = at.copy()
        for joint, keys in problem.keys.items():
            if trial_cost[joint] < cost[joint]:  # (each joint on its own cost)
                for key in keys:
                    accepted.joints[key][joint] = trial_at.joints[key][joint]
                damping[joint] = max(damping[joint] / 3.0, 1e-7)
            else:
                damping[joint] *= 4.0
        if problem.with_mass:
            if trial_cost.sum() < cost.sum():
                accepted.mass_scale = trial_at.mass_scale
                damping[-1] = max(damping[-1] / 3.0, 1e-7)
            else:
                damping[-1] *= 4.0
        mine = np.array(sorted(problem.keys))  # (the others' costs move by the coupling alone)
        cost, trial_cost = cost[mine], trial_cost[mine]
        improved = trial_cost < cost
        gain = float(np.sum((cost - trial_cost)[improved])) / max(float(cost.sum()), 1e-300)
        say(
            f"  iteration {done}: cost {cost.sum():.6g} -> "
            f"{np.where(improved, trial_cost, cost).sum():.6g}, {improved.sum()} of "
            f"{len(cost)} joints improved"
        )
        at = accepted
        if improved.any() or (problem.with_mass and accepted.mass_scale != linearised_mass):
            linearised = None
        if improved.any() and gain < tolerance:  # (a step every joint refused: not the end)
            converged = True
            break
    return at, converged, done
