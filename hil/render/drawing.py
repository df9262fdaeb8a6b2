"""The pictures of a run: a side view of the robot (the paper's Fig. 8 is a side view of
DYROS-JET stepping onto the object), snapshots at chosen instants put in one strip, and a
video of the whole run.

Camera: looking along +y at the robot's plane of motion (the humanoid walks along +x, the
testbed's link swings in x-z). The humanoid's snapshots are framed on the object it steps onto
(on the robot's pelvis without one), its video follows the pelvis along x.

The default instants: for step-on-object, the paper's five (7.2, 7.6, 8.3, 8.8, 9.4 s) shifted
so that the first is the lift-off of the foot that steps onto the box in this product's plan
(its timeline is not the paper's: the paper's plan is not published with its timing); for
another run, five instants spread over it.
"""

from __future__ import annotations

import os
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from hil.output.rundir import RunData
from hil.render import GL_MISSING
from hil.render.process import GlUnavailable
from hil.render.scene import RunScene, WorldObjects

PAPER_FIG8_S = (7.2, 7.6, 8.3, 8.8, 9.4)
STEP_ON_OBJECT = "step-on-object"
SNAPSHOT_SIZE = (480, 400)  # width, height [px]
VIDEO_SIZE = (640, 480)
VIDEO_FPS = 25
_HUMANOID_VIEW = {"distance": 2.6, "elevation": -8.0, "height_m": 0.55}
_TESTBED_VIEW = {"distance": 1.7, "elevation": -5.0, "height_m": -0.1, "x_m": 0.35}


def open_renderer(scene: RunScene, width: int, height: int) -> Any:
    """MuJoCo's offscreen renderer (MUJOCO_GL as set, else EGL), or GlUnavailable."""
    os.environ.setdefault("MUJOCO_GL", "egl")
    import mujoco

    try:
        return mujoco.Renderer(scene.model, height=height, width=width)
    except Exception as exc:  # noqa: BLE001 - the GL libraries raise their own kinds
        raise GlUnavailable(f"{GL_MISSING} ({type(exc).__name__}: {exc})") from None


def default_instants(run: RunData) -> tuple[float, ...]:
    """The instants `hil render` draws when none are given (module docstring)."""
    if run.meta.get("experiment") == STEP_ON_OBJECT:
        lift_off = _object_step_lift_off_s(run)
        if lift_off is not None:
            return tuple(lift_off + t - PAPER_FIG8_S[0] for t in PAPER_FIG8_S)
    end = float(run.time_s[-1])
    return tuple(float(t) for t in np.linspace(0.1 * end, 0.9 * end, 5))


def _object_step_lift_off_s(run: RunData) -> float | None:
    """Run time at which the foot that steps onto the box leaves the floor (the plan's)."""
    from hil.robots import get_experiment

    experiment: Any = get_experiment(STEP_ON_OBJECT)
    timeline = experiment.pattern.timeline
    singles = [s for s in timeline.segments if s.kind.value == "single_support"]
    if experiment.object_footstep >= len(singles):
        return None
    start = singles[experiment.object_footstep].start_tick * experiment.pattern.dt_s
    return run.experiment_start_s + start


def _camera(scene: RunScene, row: int, world: WorldObjects, follow: bool) -> Any:
    import mujoco

    camera = mujoco.MjvCamera()
    camera.type = mujoco.mjtCamera.mjCAMERA_FREE
    camera.azimuth = 90.0  # looking along +y: x to the right, z up
    if scene.humanoid:
        view = _HUMANOID_VIEW
        framed_on_object = bool(world.boxes) and not follow
        x = float(world.boxes[0][0][0]) if framed_on_object else scene.pelvis_x(row)
        camera.lookat[:] = (x, 0.0, view["height_m"])
    else:
        view = _TESTBED_VIEW
        camera.lookat[:] = (view["x_m"], 0.0, view["height_m"])
    camera.distance = view["distance"]
    camera.elevation = view["elevation"]
    return camera


def snapshots(
    scene: RunScene, world: WorldObjects, times_s: Sequence[float], size: tuple[int, int]
) -> list[np.ndarray]:
    """One RGB image per instant."""
    renderer = open_renderer(scene, *size)
    images = []
    try:
        for time_s in times_s:
            row = scene.row_at(time_s)
            scene.pose(row)
            renderer.update_scene(scene.data, camera=_camera(scene, row, world, follow=False))
            images.append(renderer.render().copy())
    finally:
        renderer.close()
    return images


def save_strip(
    images: Sequence[np.ndarray], times_s: Sequence[float], title: str, path: Path
) -> Path:
    """The snapshots side by side, each under its instant, as a PNG."""
    from matplotlib.figure import Figure

    n = len(images)
    height, width = images[0].shape[:2]
    figure = Figure(figsize=(n * width / 100, height / 100 + 0.6), dpi=100, layout="constrained")
    for i, (image, time_s) in enumerate(zip(images, times_s, strict=True)):
        ax = figure.add_subplot(1, n, i + 1)
        ax.imshow(image)
        ax.set_title(f"{time_s:.2f} s", fontsize=10)
        ax.set_axis_off()
    figure.suptitle(title, fontsize=10)
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path)
    return path


def video_frames(
    scene: RunScene, world: WorldObjects, fps: int, size: tuple[int, int]
) -> Iterator[np.ndarray]:
    """The run at `fps` frames per second of run time, the camera following the robot."""
    renderer = open_renderer(scene, *size)
    try:
        for time_s in np.arange(0.0, float(scene.run.time_s[-1]), 1.0 / fps):
            row = scene.row_at(float(time_s))
            scene.pose(row)
            renderer.update_scene(scene.data, camera=_camera(scene, row, world, follow=True))
            yield renderer.render().copy()
    finally:
        renderer.close()


def write_video(frames: Iterator[np.ndarray], path: Path, fps: int, size: tuple[int, int]) -> Path:
    """MP4 (H.264) through the ffmpeg imageio-ffmpeg ships; a .gif through Pillow."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.suffix.lower() == ".gif":
        from PIL import Image

        pictures = [Image.fromarray(frame) for frame in frames]
        pictures[0].save(
            path, save_all=True, append_images=pictures[1:], duration=1000 // fps, loop=0
        )
        return path
    try:
        import imageio_ffmpeg
    except ImportError:
        raise GlUnavailable(
            "an MP4 video needs imageio-ffmpeg (pip install 'flexjoint-hil[render]'); or name a "
            ".gif"
        ) from None
    writer = imageio_ffmpeg.write_frames(
        str(path), size, fps=fps, codec="libx264", pix_fmt_out="yuv420p", macro_block_size=8
    )
    writer.send(None)
    try:
        for frame in frames:
            writer.send(np.ascontiguousarray(frame))
    finally:
        writer.close()
    return path


def render_run(
    run: RunData, times_s: Sequence[float] | None, strip: Path, video: Path | None = None
) -> list[Path]:
    """`hil render`: the strip of snapshots (and the video); the files written."""
    from hil.render.scene import world_objects_of

    world = world_objects_of(run)
    scene = RunScene(run, world)
    instants = tuple(times_s) if times_s else default_instants(run)
    images = snapshots(scene, world, instants, SNAPSHOT_SIZE)
    title = str(run.meta.get("experiment_title") or run.meta.get("experiment") or "")
    note = "drawn from the log's link angles"
    if scene.humanoid:
        note += (
            "; the pelvis from the emulator's truth"
            if scene.base_from_truth
            else "; the pelvis by leg odometry (not logged)"
        )
    written = [save_strip(images, instants, f"{title}\n{run.label}: {note}", strip)]
    if video is not None:
        frames = video_frames(scene, world, VIDEO_FPS, VIDEO_SIZE)
        written.append(write_video(frames, video, VIDEO_FPS, VIDEO_SIZE))
    return written
