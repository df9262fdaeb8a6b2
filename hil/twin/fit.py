"""The twin's fit: the emulator's figures that make it replay the recorded runs.

1. A start: `hil identify`'s fits (K, D, the cascade, the motor side; hil/identify) on the
   identification runs among them, told the recorded [model]'s link inertia and gravity moment
   (without one, the recorded emulator's figures).
2. The rollout fit: the recorded goals replayed open loop on the in-process emulator
   (hil/twin/replay.py, the plant's smooth state) and the differences from the record - motor
   angle, link angle, motor current, each weighted by its rms at the start - minimised over the
   figures by scipy's trust-region least squares within bounds (`scipy.optimize.least_squares`,
   its forward-difference Jacobian's columns replayed `workers` at a time), on every run's samples
   before its held-out point (an identification run's validation sweep; else its last quarter).
   The current carries the torque's absolute scale (the torque constant is the data sheet's),
   the link's motion K / I and g m r / I: together they give I and m r.
3. The gearbox's friction model chosen by the held-out samples: from the coulomb-viscous fit,
   each other model's own figures (with the friction's) are fitted, every model's cost is
   measured on the held-out samples, and the lowest wins - then, if it is not
   coulomb-viscous, all figures are fitted again with it.
4. Intervals (95 %) from the Jacobian at the optimum and the Newey-West sandwich over the
   time-correlated residuals (hil/identify/covariance.py), per run; correlations above
   `correlation_limit` and directions the data do not see (the Jacobian's rank) are named.
   The link encoder's zero (a common offset of both encoders) is seen only through gravity's
   torque changing with the angle as the link swings: its interval says how well. A delay of
   the link encoder is estimated at the optimum (`link_delay_s`), not fitted: the emulator has
   no delay.

A fit the data cannot carry is said (`TwinFit.problems`): a figure whose interval is wider
than `interval_limit` of its value, a held-out link-angle residual above
`residual_limit_rad`, a fit window shorter than the identification needs, a run that reached
the current limit or whose excitation was rewritten, a solver that did not converge.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.optimize
import scipy.stats

from hil.config import Config, ConfigError
from hil.identify.covariance import sandwich_covariance
from hil.identify.records import MIN_SAMPLES
from hil.twin.executor import ReplayExecutor, install_runs, installed, one_blas_thread
from hil.twin.figures import (
    COMMON,
    FIGURES,
    FRICTION_FIGURES,
    Scale,
    figures_of,
    friction_of,
    link_coefficients,
    single_joint,
    twin_config,
)
from hil.twin.replay import Reading, replay_goals
from hil.twin.runs import RecordedRun, first_torque_tick, judge_run
from sim_backend.friction import GearboxFriction

CHANNELS = ("motor_angle_rad", "link_angle_rad", "motor_current_a")
# the weights' floors: a channel the model follows to its quantisation still counts that much
CHANNEL_FLOORS = (2e-5, 1e-5, 0.02)
LOG_BOUND = 3.0  # a logarithmic figure within e^+-3 (x20) of its start
FD_STEP = 1e-4  # the Jacobian's step in fit coordinates (0.01 % of a logarithmic figure)
START_MARGIN = 1e-2  # how far inside its bound a figure starts (fit coordinates)
# Where each friction model's own figures start from the coulomb-viscous optimum.
MODEL_STARTS: dict[GearboxFriction, dict[str, float]] = {
    GearboxFriction.COULOMB_VISCOUS: {},
    GearboxFriction.STRIBECK: {
        "gearbox_stribeck_friction_nm": 0.5,
        "gearbox_stribeck_velocity_rad_s": 0.05,
    },
    GearboxFriction.LOAD_DEPENDENT: {"gearbox_load_friction_ratio": 0.05},
}


@dataclass(frozen=True)
class FitOptions:
    """How to fit (see the module docstring)."""

    holdout_fraction: float = 0.25
    workers: int = 1
    max_iterations: int = 20  # residual evaluations of the solver (each: a Jacobian too)
    friction_iterations: int = 8  # the same for each friction model's own figures
    # relative change of the cost that ends the fit: a figure one standard deviation off its
    # optimum costs ~1 / (the residuals' count) of the cost, so this is a fraction of that
    tolerance: float = 1e-8
    confidence: float = 0.95
    interval_limit: float = 0.1
    correlation_limit: float = 0.98
    residual_limit_rad: float = 1.0e-3
    friction_models: tuple[GearboxFriction, ...] = tuple(GearboxFriction)
    ray: str | None = None  # the replays as Ray tasks: a cluster's address, "" a local Ray


@dataclass(frozen=True)
class Estimate:
    value: float
    low: float
    high: float
    unit: str
    fitted: bool = True  # False: estimated at the optimum, the twin keeps the recorded value
    note: str = ""

    @property
    def relative_half_width(self) -> float:
        return (self.high - self.low) / (2 * abs(self.value)) if self.value else math.inf


@dataclass(frozen=True)
class ModelScore:
    """One friction model's cost on the held-out samples (and its link-angle rms there)."""

    model: GearboxFriction
    held_out_cost: float
    held_out_link_rms_rad: float


@dataclass
class TwinFit:
    config: Config
    friction: GearboxFriction
    estimates: dict[str, Estimate]
    scores: list[ModelScore]
    correlations: list[tuple[str, str, float]]
    held_out_rms: dict[str, float]  # per channel, over every run's held-out samples
    problems: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    @property
    def trusted(self) -> bool:
        return not self.problems


# ----------------------------------------------------------------------------- the residual


@dataclass(frozen=True)
class Problem:
    """What one residual evaluation fits: which figures (from which start), with which model,
    on which rows of each run, weighted how."""

    keys: tuple[str, ...]
    start: dict[str, float]
    friction: GearboxFriction
    rows: tuple[tuple[int, int], ...]  # per run: [first, stop) of the samples compared
    weights: tuple[float, ...]

    def values(self, x: np.ndarray) -> dict[str, float]:
        out = dict(self.start)
        for key, xi in zip(self.keys, x, strict=True):
            figure = FIGURES[key]
            if figure.scale is Scale.LOG:
                out[key] = self.start[key] * math.exp(xi)
            else:
                out[key] = self.start[key] + figure.step * xi
        return out

    def bounds(self) -> list[np.ndarray]:
        low, high = [], []
        for key in self.keys:
            figure = FIGURES[key]
            if figure.scale is Scale.LOG:
                low.append(-LOG_BOUND)
                high.append(LOG_BOUND)
            else:
                floor = (figure.lower - self.start[key]) / figure.step
                low.append(max(floor, -1e3) if math.isfinite(floor) else -1e3)
                high.append(1e3)
        return [np.array(low), np.array(high)]


def _blocks(problem: Problem, x: np.ndarray) -> list[np.ndarray]:
    """Per run, (rows, channels) of weighted replayed - recorded, NaN rows zeroed."""
    runs, base = installed()
    config = twin_config(base, problem.values(x), problem.friction)
    out = []
    for run, (first, stop) in zip(runs, problem.rows, strict=True):
        replayed = replay_goals(config, run, Reading.PLANT, ticks=stop)
        if replayed.unstable:  # figures MuJoCo cannot integrate: out of the emulator's reach
            raise ValueError("the replay's integration was unstable")
        columns = []
        for channel, weight in zip(CHANNELS, problem.weights, strict=True):
            recorded = run.signal(channel)[:stop]
            difference = (replayed.signal(channel) - recorded)[first:stop, 0]
            columns.append(np.nan_to_num(difference, nan=0.0) * weight)
        out.append(np.column_stack(columns))
    return out


def _flat(args: tuple[Problem, np.ndarray]) -> np.ndarray:
    """The weighted residual of one point; infinite where the figures make no emulator (a
    link no rod and load make, a figure out of its range): the solver steps back."""
    problem, x = args
    try:
        return np.concatenate([b.ravel() for b in _blocks(problem, x)])
    except (ValueError, ConfigError):
        size = sum(stop - first for first, stop in problem.rows) * len(CHANNELS)
        return np.full(size, np.inf)


class _Evaluator:
    """Residuals of many points, `workers` at a time (forks of this process, or Ray tasks)."""

    def __init__(
        self, runs: list[RecordedRun], base: Config, workers: int, ray: str | None = None
    ) -> None:
        self.executor: ReplayExecutor[tuple[Problem, np.ndarray], np.ndarray] = ReplayExecutor(
            _flat, install_runs, (runs, base), workers, ray
        )

    def many(self, problem: Problem, xs: list[np.ndarray]) -> list[np.ndarray]:
        return self.executor.many([(problem, x) for x in xs])

    def close(self) -> None:
        self.executor.close()


def _solve(
    evaluator: _Evaluator, problem: Problem, options: FitOptions, evaluations: int | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool]:
    """(x, residual, Jacobian at x, converged): scipy's trust-region least squares within the
    figures' bounds, its forward-difference Jacobian's columns replayed `workers` at a time."""
    n = len(problem.keys)
    cache: dict[bytes, np.ndarray] = {}

    def residual(x: np.ndarray) -> np.ndarray:
        key = np.asarray(x, dtype=float).tobytes()
        if key not in cache:
            cache.clear()
            cache[key] = evaluator.many(problem, [np.asarray(x, dtype=float)])[0]
        return cache[key]

    def jacobian(x: np.ndarray) -> np.ndarray:
        r0 = residual(x)
        low, high = problem.bounds()
        steps = [FD_STEP if x[i] + FD_STEP <= high[i] else -FD_STEP for i in range(n)]
        points = []
        for i in range(n):
            point = np.array(x, dtype=float)
            point[i] += steps[i]
            points.append(point)
        columns = evaluator.many(problem, points)
        for i, column in enumerate(columns):
            if not np.all(np.isfinite(column)):  # a step out of the emulator's reach: the other
                steps[i] = -steps[i]
                points[i][i] += 2 * steps[i]
                columns[i] = evaluator.many(problem, [points[i]])[0]
        return np.column_stack([(c - r0) / h for c, h in zip(columns, steps, strict=True)])

    if n == 0:
        r = residual(np.zeros(0))
        return np.zeros(0), r, np.zeros((r.size, 0)), True
    low, high = problem.bounds()
    # trf's steps shrink to nothing at a bound: a figure that starts on one starts just inside
    start = np.clip(np.zeros(n), low + START_MARGIN, high - START_MARGIN)
    solution = scipy.optimize.least_squares(
        residual,
        start,
        jac=jacobian,
        bounds=(low, high),
        method="trf",
        x_scale="jac",
        ftol=options.tolerance,
        xtol=options.tolerance,
        gtol=1e-12,
        max_nfev=evaluations or options.max_iterations,
    )
    x = solution.x
    return x, residual(x), jacobian(x), bool(solution.status > 0)


# ----------------------------------------------------------------------------- the fit


def _split(run: RecordedRun, options: FitOptions) -> int:
    start = run.validation_start_s
    if start is not None:
        return int(np.searchsorted(run.run.time_s, start))
    return int(round((1.0 - options.holdout_fraction) * run.ticks))


def _start(runs: list[RecordedRun], base: Config, notes: list[str]) -> dict[str, float]:
    """The recorded emulator's figures, then `hil identify`'s where an identification run is."""
    start = figures_of(base)
    identification = [r for r in runs if r.experiment_name == "identify"]
    if not identification:
        notes.append("no identification run: the fit starts from the recorded emulator's figures")
        return start
    from hil.identify import IdentificationOptions, KnownJointFigures, LogFormatError, identify
    from hil.identify.runs import read_identification_run, validation_start_of

    try:
        read = [read_identification_run(r.out_dir) for r in identification]
        model = base.model
        limit = next(iter(read[0].current_limit_a.values()))
        known = KnownJointFigures(
            model.link_inertia_kg_m2, model.gravity_moment_kg_m, current_limit_a=limit
        )
        options = IdentificationOptions(validation_start_s=validation_start_of(read))
        result = identify([log for r in read for log in r.logs.values()], known, options)
    except (LogFormatError, ValueError) as exc:
        notes.append(f"hil identify's fit failed ({exc}): starting from the emulator's figures")
        return start
    from hil.identify import Parameter as P

    value = {p: result[p].value for p in P}
    start.update(
        {
            "gear_stiffness_nm_per_rad": value[P.GEAR_STIFFNESS],
            "gear_damping_nms_per_rad": value[P.GEAR_DAMPING],
            "position_gain_per_s": value[P.POSITION_GAIN],
            "velocity_gain_nms_per_rad": value[P.VELOCITY_GAIN],
            "velocity_integral_time_s": value[P.VELOCITY_INTEGRAL_TIME],
            "motor_reflected_inertia_kg_m2": value[P.MOTOR_INERTIA],
            "gearbox_viscous_friction_nms_per_rad": max(value[P.MOTOR_VISCOUS_FRICTION], 0.0),
            "gearbox_coulomb_friction_nm": max(value[P.MOTOR_COULOMB_FRICTION], 0.0),
            # identify's delta_0 = link zero error - motor zero error, the link's taken as 0
            "motor_zero_error_rad": float(
                np.clip(-value[P.DEFLECTION_OFFSET] + start["link_zero_error_rad"], -0.09, 0.09)
            ),
        }
    )
    return start


@one_blas_thread
def fit_twin(
    runs: Sequence[RecordedRun],
    options: FitOptions | None = None,
    say: Callable[[str], None] = lambda _: None,
) -> TwinFit:
    """The twin of the robot these runs recorded (see the module docstring); `say` hears what
    stage the fit is at (a fit replays its runs some hundred times: minutes)."""
    options = options or FitOptions()
    runs = list(runs)
    base = runs[0].config
    single_joint(base)
    problems: list[str] = []
    notes: list[str] = []
    splits = [_split(r, options) for r in runs]
    fit_rows = tuple((first_torque_tick(r), s) for r, s in zip(runs, splits, strict=True))
    held_rows = tuple((s, r.ticks) for r, s in zip(runs, splits, strict=True))
    if not _judge_data(runs, fit_rows, base, problems):  # too little to fit at all
        return TwinFit(base, friction_of(base), {}, [], [], {}, problems, notes)
    start = _start(runs, base, notes)
    friction = GearboxFriction.COULOMB_VISCOUS
    evaluator = _Evaluator(runs, base, options.workers, options.ray)
    try:
        weights = _weights(evaluator, start, friction, fit_rows)
        keys = COMMON
        problem = Problem(keys, start, friction, fit_rows, weights)
        say(f"fitting {len(keys)} figures with coulomb-viscous friction")
        x, residual, jacobian, converged = _solve(evaluator, problem, options)
        values = problem.values(x)
        say("each friction model on the held-out samples")
        scores, candidates = _choose_friction(
            evaluator, values, weights, fit_rows, held_rows, options
        )
        best = min(scores, key=lambda s: s.held_out_cost)
        friction = best.model
        if friction is not GearboxFriction.COULOMB_VISCOUS:
            keys = COMMON + FRICTION_FIGURES[friction]
            say(f"fitting {len(keys)} figures with {friction.value} friction")
            problem = Problem(keys, candidates[friction], friction, fit_rows, weights)
            x, residual, jacobian, converged = _solve(evaluator, problem, options)
            values = problem.values(x)
        if not converged:
            problems.append(
                f"the rollout fit did not converge in {options.max_iterations} iterations"
            )
        estimates, correlations = _intervals(problem, x, residual, jacobian, options, problems)
        config = twin_config(base, values, friction)
        held = _held_out_rms(evaluator, Problem((), values, friction, held_rows, (1.0,) * 3))
    finally:
        evaluator.close()
    if held["link_angle_rad"] > options.residual_limit_rad:
        problems.append(
            f"the held-out link angle stays {1e3 * held['link_angle_rad']:.3g} mrad rms from the "
            f"record (limit {1e3 * options.residual_limit_rad:g} mrad): the emulator's "
            "structure does not follow this robot"
        )
    return TwinFit(config, friction, estimates, scores, correlations, held, problems, notes)


def _judge_data(
    runs: list[RecordedRun],
    rows: tuple[tuple[int, int], ...],
    base: Config,
    problems: list[str],
) -> bool:
    """What the data cannot carry, into `problems`; False: too little to fit at all."""
    fitted = sum(stop - first for first, stop in rows)
    if fitted < MIN_SAMPLES:
        problems.append(
            f"the runs hold {fitted} samples before their held-out points; the fit needs at "
            f"least {MIN_SAMPLES} (an identification run gives ~6000)"
        )
        return False
    integral_time = figures_of(base)["velocity_integral_time_s"]
    if fitted * base.loop.period_s < 2 * integral_time:
        problems.append(
            f"the fitted samples span {fitted * base.loop.period_s:.1f} s, less than twice the "
            f"servo's integral time ({integral_time:.1f} s): it cannot be determined"
        )
    for run, (first, stop) in zip(runs, rows, strict=True):
        limits = run.run.summary.get("current_limit_a") or []
        current = np.abs(run.signal("motor_current_a")[first:stop, 0])
        if limits and isinstance(limits[0], int | float):
            saturated = np.count_nonzero(current >= 0.98 * float(limits[0]))
            if saturated > 0.01 * max(stop - first, 1):
                problems.append(
                    f"{run.out_dir}: the current sat at its limit on {saturated} samples: the "
                    "servo's law is not seen there (excite with less amplitude)"
                )
        judge_run(run, problems)
    return True


def _weights(
    evaluator: _Evaluator,
    start: dict[str, float],
    friction: GearboxFriction,
    rows: tuple[tuple[int, int], ...],
) -> tuple[float, ...]:
    """1 / each channel's rms at the start (floored at its quantisation)."""
    problem = Problem((), start, friction, rows, (1.0,) * len(CHANNELS))
    flat = evaluator.many(problem, [np.zeros(0)])[0].reshape(-1, len(CHANNELS))
    rms = np.sqrt(np.mean(flat**2, axis=0))
    return tuple(1.0 / max(r, floor) for r, floor in zip(rms, CHANNEL_FLOORS, strict=True))


def _held_out_cost(evaluator: _Evaluator, problem: Problem) -> tuple[float, float]:
    flat = evaluator.many(problem, [np.zeros(len(problem.keys))])[0]
    blocks = flat.reshape(-1, len(CHANNELS))
    link = blocks[:, 1] / problem.weights[1]
    return float(np.mean(blocks**2)), float(np.sqrt(np.mean(link**2)))


def _choose_friction(
    evaluator: _Evaluator,
    values: dict[str, float],
    weights: tuple[float, ...],
    fit_rows: tuple[tuple[int, int], ...],
    held_rows: tuple[tuple[int, int], ...],
    options: FitOptions,
) -> tuple[list[ModelScore], dict[GearboxFriction, dict[str, float]]]:
    """Each model's own figures fitted (with the friction's and the rotor's) from the
    coulomb-viscous optimum, then scored on the held-out samples."""
    scores, candidates = [], {}
    for model in options.friction_models:
        candidate = dict(values)
        own = FRICTION_FIGURES[model]
        if own:
            start = {**values, **MODEL_STARTS[model]}
            keys = (
                "gearbox_coulomb_friction_nm",
                "gearbox_viscous_friction_nms_per_rad",
                "motor_reflected_inertia_kg_m2",
                *own,
            )
            problem = Problem(keys, start, model, fit_rows, weights)
            x, *_ = _solve(evaluator, problem, options, options.friction_iterations)
            candidate = problem.values(x)
        candidates[model] = candidate
        cost, link = _held_out_cost(evaluator, Problem((), candidate, model, held_rows, weights))
        scores.append(ModelScore(model, cost, link))
    return scores, candidates


def _intervals(
    problem: Problem,
    x: np.ndarray,
    residual: np.ndarray,
    jacobian: np.ndarray,
    options: FitOptions,
    problems: list[str],
) -> tuple[dict[str, Estimate], list[tuple[str, str, float]]]:
    """Intervals of the fitted figures (and the link's I and m r), the correlations above the
    limit, a Jacobian of too low a rank."""
    values = problem.values(x)
    z = scipy.stats.norm.ppf(0.5 + options.confidence / 2)
    channels, n = len(CHANNELS), len(problem.keys)
    offsets = np.cumsum([0, *(stop - first for first, stop in problem.rows)])
    spans = list(zip(offsets[:-1], offsets[1:], strict=True))
    covariance = sandwich_covariance(
        [jacobian[channels * a : channels * b].reshape(-1, channels, n) for a, b in spans],
        [residual[channels * a : channels * b].reshape(-1, channels) for a, b in spans],
    )
    half = z * np.sqrt(np.maximum(np.diag(covariance), 0.0))
    estimates: dict[str, Estimate] = {}
    for i, key in enumerate(problem.keys):
        figure = FIGURES[key]
        if figure.scale is Scale.LOG:
            low, high = values[key] * math.exp(-half[i]), values[key] * math.exp(half[i])
        else:
            low, high = values[key] - figure.step * half[i], values[key] + figure.step * half[i]
        estimates[key] = Estimate(values[key], low, high, figure.unit)
    estimates.update(_link_estimates(problem, values, covariance, z))
    sd = np.sqrt(np.maximum(np.diag(covariance), 1e-300))
    corr = covariance / np.outer(sd, sd)
    correlations = [
        (problem.keys[i], problem.keys[j], float(corr[i, j]))
        for i in range(n)
        for j in range(i + 1, n)
        if abs(corr[i, j]) > options.correlation_limit
    ]
    singular = np.linalg.svd(jacobian, compute_uv=False)
    rank = int(np.count_nonzero(singular > singular[0] * 1e-8))
    if rank < n:
        problems.append(
            f"the data see {rank} of the {n} fitted figures' directions: some combination of "
            "them is not determined (see the correlations)"
        )
    _judge_intervals(problem.keys, estimates, options, problems)
    return estimates, correlations


def _judge_intervals(
    keys: Sequence[str],
    estimates: dict[str, Estimate],
    options: FitOptions,
    problems: list[str],
) -> None:
    """A figure whose interval is wider than the options allow is not determined."""
    for key in keys:
        estimate = estimates[key]
        if estimate.unit == "rad":
            if estimate.high - estimate.low > 2 * options.residual_limit_rad:
                problems.append(
                    f"{key}: the 95 % interval is {1e3 * (estimate.high - estimate.low):.2g} "
                    "mrad wide: not determined by these runs"
                )
        elif not estimate.relative_half_width < options.interval_limit:
            problems.append(
                f"{key}: the 95 % interval is +-{100 * estimate.relative_half_width:.0f} % of its "
                "value: not determined by these runs"
            )


def _link_estimates(
    problem: Problem, values: dict[str, float], covariance: np.ndarray, z: float
) -> dict[str, Estimate]:
    """The link's I and m r from the fitted masses (linear in them), intervals by their
    gradient through the covariance."""
    plant = twin_config(installed()[1], values, problem.friction)
    from hil.wiring.emulation import plant_servo_noise

    params = plant_servo_noise(plant)[0]
    out = {}
    for (rod, load), key, unit in zip(
        link_coefficients(params),
        ("link_inertia_kg_m2", "gravity_moment_kg_m"),
        ("kg m^2", "kg m"),
        strict=True,
    ):
        gradient = np.zeros(len(problem.keys))
        for name, coefficient in (("link_mass_kg", rod), ("load_mass_kg", load)):
            if name in problem.keys:  # d value / d log(mass) = coefficient x mass
                gradient[problem.keys.index(name)] = coefficient * values[name]
        value = rod * values["link_mass_kg"] + load * values["load_mass_kg"]
        half = z * math.sqrt(max(float(gradient @ covariance @ gradient), 0.0))
        out[key] = Estimate(value, value - half, value + half, unit)
    return out


def _held_out_rms(evaluator: _Evaluator, problem: Problem) -> dict[str, float]:
    flat = evaluator.many(problem, [np.zeros(0)])[0].reshape(-1, len(CHANNELS))
    return {channel: float(np.sqrt(np.mean(flat[:, i] ** 2))) for i, channel in enumerate(CHANNELS)}


def link_delay_s(runs: Sequence[RecordedRun], config: Config, confidence: float = 0.95) -> Estimate:
    """How late the link encoder reads against the twin's replay: r(t) ~ tau v(t) fitted by
    least squares over every run (the replayed link velocity v), with its interval."""
    numerator = denominator = 0.0
    residuals, velocities = [], []
    for run in runs:
        replayed = replay_goals(config, run, Reading.PLANT)
        link = replayed.link_angle_rad[:, 0]
        velocity = np.gradient(link, run.period_s)
        r = np.nan_to_num(link - run.signal("link_angle_rad")[:, 0])
        residuals.append(r)
        velocities.append(velocity)
        numerator += float(np.dot(r, velocity))
        denominator += float(np.dot(velocity, velocity))
    tau = numerator / denominator if denominator > 0 else 0.0
    jac = [v.reshape(-1, 1, 1) for v in velocities]
    res = [(r - tau * v).reshape(-1, 1) for r, v in zip(residuals, velocities, strict=True)]
    half = scipy.stats.norm.ppf(0.5 + confidence / 2) * math.sqrt(
        max(sandwich_covariance(jac, res)[0, 0], 0.0)
    )
    return Estimate(
        tau, tau - half, tau + half, "s", fitted=False, note="the emulator has no encoder delay"
    )
