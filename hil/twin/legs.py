"""The twin of DYROS-JET's legs: the emulator's figures of its twelve joints fitted to recorded
runs, above all the suspended excitation (hil/experiments/suspended.py).

The residual is the testbed's (hil/twin/fit.py): the recorded goals and torque states replayed
open loop on the in-process emulator (the whole robot: MuJoCo, the twelve firmwares), the
differences of each joint's motor angle, link angle and current from the record, each weighted
by 1 / its rms at the start. What differs is the size: ~10 figures a joint, 121 in all, where
every residual evaluation is a replay of the whole robot (~10 s for the 66 s excitation). A
forward-difference Jacobian of all 121 columns would cost 121 replays an iteration; but the
residual has a structure the fit uses:

- a joint's figures act on its own signals first: its servo and gear make its motor's and
  link's motion and its current, while the other joints' figures reach it only through the
  links' coupling, which the suspended excitation keeps small (one joint of each leg moves at
  a time, the others hold their goals; the pelvis is fixed, so the two legs do not act on each
  other at all);
- so one replay with a figure changed on all twelve joints at once gives, joint by joint, the
  column of that joint's figure (each joint's own rows): ~11 replays an iteration (10 figures
  and the mass scale, whose column is every joint's rows), run `workers` at a time.

The solver is Levenberg-Marquardt on that block Jacobian (its normal equations: a block per
joint and the mass scale's row and column across them, solved whole), with a damping per joint
and a step accepted joint by joint on that joint's own cost (a joint whose cost the step raised
keeps its figures and its damping grows): what the neglected coupling gets wrong shows as a
rejected step, never as a wrong optimum, because the cost is always the whole robot's replay.
scipy's `least_squares` takes a Jacobian but not a per-block acceptance; with the coupling
neglected its single trust region shrank for all twelve joints whenever one joint's step failed.

The friction model is chosen per joint on the held-out samples (the suspended excitation's
down-sweeps), as on the testbed: from the coulomb-viscous optimum each other model's own figures
are fitted (with the friction's and the rotor's) on every joint at once, each joint's cost on
its held-out samples is compared across the models, the lowest wins, and every figure is fitted
again with each joint's model.

Intervals (95 %): per joint from its block of the Jacobian at the optimum and the Newey-West
sandwich over its time-correlated residuals (hil/identify/covariance.py) - conditional on the
other joints' figures, as the block Jacobian is; the mass scale's from its column over every
joint. A fit the data cannot carry says so (`LegsFit.problems`): a figure whose interval is
wider than the limit, a joint's held-out link angle farther than `residual_limit_rad` from the
record, a fit that did not converge, a run that did not complete or whose excitation the
supervisor rewrote.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.optimize
import scipy.stats

from hil.config import Config
from hil.identify.covariance import sandwich_covariance
from hil.twin.block_lm import (
    FD_STEP,
    Problem,
    Replays,
    Rows,
    jacobian,
    joint_costs,
    joint_residuals,
    moved_figures,
    normal_equations,
    solve,
)
from hil.twin.executor import one_blas_thread
from hil.twin.figures import FRICTION_FIGURES, Scale
from hil.twin.fit import (
    CHANNEL_FLOORS,
    CHANNELS,
    LOG_BOUND,
    MODEL_STARTS,
    Estimate,
)
from hil.twin.legs_figures import (
    JOINT_FIGURES,
    MASS_SCALE,
    LegFigures,
    figure,
    leg_figures_of,
    legs_robot,
    legs_twin_config,
)
from hil.twin.runs import RecordedRun, first_torque_tick, judge_run
from sim_backend.friction import GearboxFriction

FRICTION_KEYS = (
    "gearbox_coulomb_friction_nm",
    "gearbox_viscous_friction_nms_per_rad",
    "motor_reflected_inertia_kg_m2",
)


@dataclass(frozen=True)
class LegsFitOptions:
    """How to fit the legs (see the module docstring)."""

    workers: int = 1
    max_iterations: int = 12  # Levenberg-Marquardt iterations of the full fit
    friction_iterations: int = 4  # the same for each friction model's own figures
    tolerance: float = 1e-4  # relative change of the whole cost that ends the fit
    confidence: float = 0.95
    interval_limit: float = 0.1
    residual_limit_rad: float = 1.0e-3
    friction_models: tuple[GearboxFriction, ...] = tuple(GearboxFriction)
    # a friction model with figures of its own is chosen for a joint only if it lowers the
    # joint's held-out cost by this fraction: on the default emulator's own runs the three
    # models' held-out costs differ by < 0.1 % (the current's noise), and a figure fitted to
    # noise is one the fit cannot determine
    model_margin: float = 0.01
    fit_mass_scale: bool = True
    ray: str | None = None  # the replays as Ray tasks: a cluster's address, "" a local Ray


@dataclass
class LegsFit:
    """The fit of the legs: the twin, its figures with intervals per joint, the friction model
    each joint's held-out samples chose, what cannot be trusted."""

    config: Config
    figures: LegFigures
    estimates: dict[str, list[Estimate]]  # per figure, one per joint (mass_scale: one)
    scores: dict[GearboxFriction, np.ndarray]  # per model, each joint's held-out cost
    held_out_rms: dict[str, np.ndarray]  # per channel, each joint's rms on held-out samples
    iterations: int
    problems: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    @property
    def trusted(self) -> bool:
        return not self.problems


# ------------------------------------------------------------------------------ the fit


def _rows(runs: list[RecordedRun]) -> tuple[Rows, Rows]:
    """(fit, held out) per run: the experiment's held-out windows where it has them (the
    suspended excitation), else the last quarter; the fit's rows start after torque is on."""
    fit, held = [], []
    for run in runs:
        ticks = run.ticks
        first = first_torque_tick(run)
        out = np.zeros(ticks, dtype=bool)
        experiment_rows = np.flatnonzero(np.asarray(run.run.columns.get("phase")) == "experiment")
        mask_of = getattr(run.experiment, "held_out_mask", None)
        if mask_of is not None and experiment_rows.size:
            mask = mask_of(run.period_s, experiment_rows.size)
            out[experiment_rows[mask]] = True
        else:
            out[int(round(0.75 * ticks)) :] = True
        usable = np.arange(ticks) >= first
        fit.append(usable & ~out)
        held.append(usable & out)
    return Rows(tuple(fit)), Rows(tuple(held))


def _weights(blocks: list[np.ndarray], rows: Rows) -> np.ndarray:
    """(channels, joints): 1 / each joint's channel rms at the start, floored."""
    stacked = np.concatenate([b[m] for b, m in zip(blocks, rows.masks, strict=True)])
    rms = np.sqrt(np.mean(stacked**2, axis=0))  # (channels, joints)
    floors = np.array(CHANNEL_FLOORS)[:, None]
    return 1.0 / np.maximum(rms, floors)


@one_blas_thread
def fit_legs(
    runs: Sequence[RecordedRun],
    options: LegsFitOptions | None = None,
    say: Callable[[str], None] = lambda _: None,
) -> LegsFit:
    """The twin of DYROS-JET's legs from these runs (module docstring); `say` hears the stages
    (a fit replays the runs some hundred times: tens of minutes for the suspended excitation
    on one worker)."""
    options = options or LegsFitOptions()
    runs = list(runs)
    base = runs[0].config
    legs_robot(base)
    problems: list[str] = []
    notes: list[str] = []
    for run in runs:
        judge_run(run, problems)
    if not any(r.experiment.world.suspended for r in runs):
        notes.append(
            "no suspended run: on its feet the robot's legs move together and the fit's block "
            "Jacobian is a poorer guide (record `hil run suspended-chirp`)"
        )
    hung = [r for r in runs if r.experiment.world.suspended] or runs
    on_feet = [r for r in runs if r not in hung]
    hanging = _fit_hung(hung, base, options, say)
    chosen, estimates = hanging.figures, hanging.estimates
    if not hanging.converged:
        problems.append(f"the rollout fit did not converge in {options.max_iterations} iterations")
    unseen = _undetermined(estimates, options)
    if on_feet and unseen:
        names = ", ".join(f"{base.joint_names[j]} {k}" for j, k in unseen)
        say(f"on the feet ({len(on_feet)} run(s)): {names}")
        chosen, refitted = _fit_on_feet(on_feet, base, chosen, unseen, options, say)
        for (joint, key), estimate in refitted.items():
            estimates[key][joint] = estimate
    elif unseen:
        notes.append(
            "figures the suspended excitation cannot determine (a gear that carries only a "
            "foot: too light to deflect it) are fitted from a run on the feet when one is "
            "given (`hil run push` suits: the weight and a push on every joint)"
        )
    _judge(estimates, hanging.held_out_rms, base.joint_names, options, problems)
    config = legs_twin_config(base, chosen)
    return LegsFit(config, chosen, estimates, hanging.scores, hanging.held_out_rms,
                   hanging.iterations, problems, notes)  # fmt: skip


@dataclass
class _Hanging:
    """What the suspended runs gave: the figures, their intervals, each model's held-out cost
    per joint, the held-out rms per channel and joint."""

    figures: LegFigures
    estimates: dict[str, list[Estimate]]
    scores: dict[GearboxFriction, np.ndarray]
    held_out_rms: dict[str, np.ndarray]
    converged: bool
    iterations: int


def _fit_hung(
    runs: list[RecordedRun], base: Config, options: LegsFitOptions, say: Callable[[str], None]
) -> _Hanging:
    """Every figure of every joint from the suspended runs (the module docstring's fit)."""
    start = leg_figures_of(base)
    n = len(base.joints)
    fit_rows, held_rows = _rows(runs)
    replays = Replays(runs, base, options.workers, options.ray)
    try:
        first = replays.many([start])[0]
        if first is None:
            raise ValueError("the recorded configuration makes no emulator")
        weights = _weights(first, fit_rows)
        say(f"fitting {len(JOINT_FIGURES)} figures on each of {n} joints, coulomb-viscous")
        common = {j: JOINT_FIGURES for j in range(n)}
        problem = Problem(common, options.fit_mass_scale, fit_rows, weights)
        values, converged, used = solve(
            replays, problem, start, options.max_iterations, options.tolerance, say
        )
        say("each friction model on the held-out samples")
        scores, candidates = _choose_friction(replays, values, weights, fit_rows, held_rows,
                                              options, say)  # fmt: skip
        chosen = values.copy()
        for j in range(n):
            best = _best_model(scores, j, options.model_margin)
            chosen.with_model(j, best, {k: float(candidates[best].joints[k][j]) for k in
                                        candidates[best].joints})  # fmt: skip
            for key in FRICTION_KEYS:
                chosen.joints[key][j] = candidates[best].joints[key][j]
        if any(m is not GearboxFriction.COULOMB_VISCOUS for m in chosen.models):
            say("fitting every figure again with each joint's friction model")
            keys = {j: chosen.keys_of(j) for j in range(n)}
            problem = Problem(keys, options.fit_mass_scale, fit_rows, weights)
            chosen, converged, more = solve(
                replays, problem, chosen, options.max_iterations, options.tolerance, say
            )
            used += more
        keys = {j: chosen.keys_of(j) for j in range(n)}
        problem = Problem(keys, options.fit_mass_scale, fit_rows, weights)
        final, moved = jacobian(replays, problem, chosen)
        assert final is not None
        _, _, _, blocks = normal_equations(problem, final, moved)
        estimates = _intervals(problem, chosen, final, blocks, moved, options)
    finally:
        replays.close()
    held = _held_rms(final, held_rows)
    return _Hanging(chosen, estimates, scores, held, converged, used)


def _undetermined(
    estimates: dict[str, list[Estimate]], options: LegsFitOptions
) -> list[tuple[int, str]]:
    """(joint, figure) whose interval is wider than the options allow (zeros: in mrad)."""
    out = []
    for key, per_joint in estimates.items():
        if key == MASS_SCALE.key:
            continue
        for joint, e in enumerate(per_joint):
            if not math.isfinite(e.value):
                continue
            wide = (
                e.high - e.low > 2 * options.residual_limit_rad
                if e.unit == "rad"
                else not e.relative_half_width < options.interval_limit
            )
            if wide:
                out.append((joint, key))
    return out


def _fit_on_feet(
    runs: list[RecordedRun],
    base: Config,
    start: LegFigures,
    columns: list[tuple[int, str]],
    options: LegsFitOptions,
    say: Callable[[str], None],
) -> tuple[LegFigures, dict[tuple[int, str], Estimate]]:
    """The figures the suspended excitation left undetermined, fitted on runs on the feet with
    every other figure held: a few figures, strongly coupled through the ground, so each has
    its own column (no block structure) and scipy's trust-region least squares solves them."""
    replays = Replays(runs, base, options.workers, options.ray)

    def values(x: np.ndarray) -> LegFigures:
        out = start
        for (joint, key), xi in zip(columns, x, strict=True):
            out = moved_figures(out, key, [joint], float(xi))
        return out

    try:
        first = replays.many([start])[0]
        if first is None:
            raise ValueError("the runs on the feet make no emulator with the fitted figures")
        rows = Rows(tuple(np.arange(r.ticks) > first_torque_tick(r) for r in runs))
        weights = _weights(first, rows)

        def flat(blocks: list[np.ndarray] | None) -> np.ndarray:
            if blocks is None:  # out of the emulator's reach: the solver steps back
                return np.full(sum(int(m.sum()) for m in rows.masks) * weights.size, np.inf)
            return np.concatenate(
                [(b[m] * weights[None]).ravel() for b, m in zip(blocks, rows.masks, strict=True)]
            )

        def residual(x: np.ndarray) -> np.ndarray:
            return flat(replays.many([values(x)])[0])

        def jacobian(x: np.ndarray) -> np.ndarray:
            points = [values(x)] + [values(x + FD_STEP * e) for e in np.eye(len(x))]
            r0, *moved = (flat(b) for b in replays.many(points))
            return np.column_stack([(r - r0) / FD_STEP for r in moved])

        solution = scipy.optimize.least_squares(
            residual, np.zeros(len(columns)), jac=jacobian, bounds=(-LOG_BOUND, LOG_BOUND),
            method="trf", x_scale="jac", ftol=options.tolerance, max_nfev=options.max_iterations,
        )  # fmt: skip
        say(f"  on the feet: cost {solution.cost:.6g} after {solution.nfev} steps")
        fitted = values(solution.x)
        jac, res = jacobian(solution.x), residual(solution.x)
    finally:
        replays.close()
    z = scipy.stats.norm.ppf(0.5 + options.confidence / 2)
    sizes = np.cumsum([0] + [int(m.sum()) * weights.size for m in rows.masks])
    spans = list(zip(sizes[:-1], sizes[1:], strict=True))
    covariance = sandwich_covariance(
        [jac[a:b].reshape(-1, weights.size, len(columns)) for a, b in spans],
        [res[a:b].reshape(-1, weights.size) for a, b in spans],
    )
    half = _unseen(jac, z * np.sqrt(np.maximum(np.diag(covariance), 0.0)))
    return fitted, {
        (joint, key): _estimate(key, float(fitted.joints[key][joint]), float(h))
        for (joint, key), h in zip(columns, half, strict=True)
    }


def _choose_friction(
    replays: Replays,
    values: LegFigures,
    weights: np.ndarray,
    fit_rows: Rows,
    held_rows: Rows,
    options: LegsFitOptions,
    say: Callable[[str], None],
) -> tuple[dict[GearboxFriction, np.ndarray], dict[GearboxFriction, LegFigures]]:
    """Each model's own figures fitted on every joint from the coulomb-viscous optimum, then
    each joint's held-out cost under each model."""
    n = len(values.models)
    scores: dict[GearboxFriction, np.ndarray] = {}
    candidates: dict[GearboxFriction, LegFigures] = {}
    for model in options.friction_models:
        candidate = values.copy()
        for j in range(n):
            candidate.with_model(j, model, MODEL_STARTS[model])
        own = FRICTION_FIGURES[model]
        if own:
            say(f"  {model.value}: its figures on every joint")
            keys = {j: FRICTION_KEYS + own for j in range(n)}
            problem = Problem(keys, False, fit_rows, weights)
            candidate, *_ = solve(
                replays, problem, candidate, options.friction_iterations, options.tolerance, say
            )
        replayed = replays.many([candidate])[0]
        scores[model] = (
            np.full(n, math.inf) if replayed is None
            else joint_costs(replayed, held_rows, weights)
        )  # fmt: skip
        candidates[model] = candidate
    return scores, candidates


def _best_model(
    scores: dict[GearboxFriction, np.ndarray], joint: int, margin: float
) -> GearboxFriction:
    """The model with the lowest held-out cost of `joint`, coulomb-viscous unless another is
    lower by more than `margin` of it."""
    best = min(scores, key=lambda m: scores[m][joint])
    plain = GearboxFriction.COULOMB_VISCOUS
    if plain in scores and scores[best][joint] > (1.0 - margin) * scores[plain][joint]:
        return plain
    return best


def _intervals(
    problem: Problem,
    values: LegFigures,
    residual: list[np.ndarray],
    blocks: dict[int, np.ndarray],
    moved: dict[str, list[np.ndarray] | None],
    options: LegsFitOptions,
) -> dict[str, list[Estimate]]:
    """Per joint, the intervals of its figures from its own block (conditional on the others);
    the mass scale's from its column over every joint."""
    z = scipy.stats.norm.ppf(0.5 + options.confidence / 2)
    n = len(values.models)
    out: dict[str, list[Estimate]] = {}
    for joint, keys in problem.keys.items():
        res = joint_residuals(residual, problem.rows, problem.weights, joint)
        sizes = np.cumsum([0] + [len(r) for r in res])
        block = blocks[joint]
        jac = [block[a:b] for a, b in zip(sizes[:-1], sizes[1:], strict=True)]
        covariance = sandwich_covariance(jac, res)
        half = _unseen(
            block.reshape(-1, len(keys)), z * np.sqrt(np.maximum(np.diag(covariance), 0.0))
        )
        for key, h in zip(keys, half, strict=True):
            out.setdefault(key, [_nothing(key)] * n)
            out[key][joint] = _estimate(key, float(values.joints[key][joint]), float(h))
    if problem.with_mass and moved.get(MASS_SCALE.key) is not None:
        other = moved[MASS_SCALE.key]
        assert other is not None
        jac, res = [], []
        for joint in problem.keys:
            r = np.concatenate(joint_residuals(residual, problem.rows, problem.weights, joint))
            m = np.concatenate(joint_residuals(other, problem.rows, problem.weights, joint))
            jac.append(((m - r) / FD_STEP)[:, :, None])
            res.append(r)
        half = z * math.sqrt(max(float(sandwich_covariance(jac, res)[0, 0]), 0.0))
        out[MASS_SCALE.key] = [_estimate(MASS_SCALE.key, values.mass_scale, half)]
    return out


def _unseen(jacobian: np.ndarray, half: np.ndarray) -> np.ndarray:
    """Half-widths with a figure the residual does not change with made infinite (the
    sandwich's pseudo-inverse would give such a column no variance at all)."""
    norms = np.linalg.norm(jacobian, axis=0)
    seen = norms > 1e-9 * max(float(norms.max(initial=0.0)), 1e-300)
    return np.where(seen, half, np.inf)


def _nothing(key: str) -> Estimate:
    return Estimate(math.nan, math.nan, math.nan, figure(key).unit, fitted=False)


def _estimate(key: str, value: float, half: float) -> Estimate:
    f = figure(key)
    if f.scale is Scale.LOG:
        return Estimate(value, value * math.exp(-half), value * math.exp(half), f.unit)
    return Estimate(value, value - f.step * half, value + f.step * half, f.unit)


def _held_rms(blocks: list[np.ndarray], rows: Rows) -> dict[str, np.ndarray]:
    stacked = np.concatenate([b[m] for b, m in zip(blocks, rows.masks, strict=True)])
    rms = np.sqrt(np.mean(stacked**2, axis=0))  # (channels, joints)
    return {channel: rms[i] for i, channel in enumerate(CHANNELS)}


def _judge(
    estimates: dict[str, list[Estimate]],
    held: dict[str, np.ndarray],
    names: Sequence[str],
    options: LegsFitOptions,
    problems: list[str],
) -> None:
    for key, per_joint in estimates.items():
        for name, estimate in zip(names, per_joint, strict=False):
            if not estimate.fitted or not math.isfinite(estimate.value):
                continue
            if estimate.unit == "rad":
                if estimate.high - estimate.low > 2 * options.residual_limit_rad:
                    problems.append(
                        f"{name} {key}: the 95 % interval is "
                        f"{1e3 * (estimate.high - estimate.low):.2g} mrad wide: not determined"
                    )
            elif not estimate.relative_half_width < options.interval_limit:
                problems.append(
                    f"{name} {key}: the 95 % interval is +-"
                    f"{100 * estimate.relative_half_width:.0f} % of its value: not determined"
                )
    for name, rms in zip(names, held["link_angle_rad"], strict=True):
        if rms > options.residual_limit_rad:
            problems.append(
                f"{name}: the held-out link angle stays {1e3 * rms:.3g} mrad rms from the record "
                f"(limit {1e3 * options.residual_limit_rad:g} mrad)"
            )
