"""`hil render`: the robot of a run drawn with MuJoCo's offscreen renderer (Mesa's EGL, as
.ci/run installs it): the pictures show the robot where the log has it (a snapshot is the same
picture at two ticks with the same angles, another one where the angles differ), the strip
has one panel per instant, a video one frame per 1/25 s of the run; the step-on-object
instants are the paper's, placed at the plan's step onto the box; without PyOpenGL the user is
told what to install."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("OpenGL")

from hil.cli import main
from hil.output.rundir import load_run
from hil.render import GL_MISSING
from hil.render.drawing import PAPER_FIG8_S, STEP_ON_OBJECT, VIDEO_FPS, default_instants


def _png(path: Path) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(path).convert("RGB"))


def _frames(path: Path) -> list[np.ndarray]:
    import imageio_ffmpeg

    reader = imageio_ffmpeg.read_frames(str(path))
    meta = next(reader)
    width, height = meta["size"]
    return [np.frombuffer(f, np.uint8).reshape(height, width, 3) for f in reader]


@pytest.mark.slow
def test_hil_render_draws_a_testbed_run_and_its_video(testbed_run: Path, tmp_path: Path) -> None:
    strip, video = tmp_path / "strip.png", tmp_path / "run.mp4"
    args = ["render", str(testbed_run), "--at", "0.5", "1.0", "2.9", "--out", str(strip)]
    assert main([*args, "--video", str(video)]) == 0
    image = _png(strip)
    assert image.shape[1] > 3 * image.shape[0]  # three panels side by side
    frames = _frames(video)
    run = load_run(testbed_run)
    assert len(frames) == int(np.ceil(run.time_s[-1] * VIDEO_FPS))
    assert frames[0].std() > 10  # a picture, not a blank
    link = np.array(run.per_joint("link_angle_rad"))[0]
    assert np.ptp(link[:9]) < 1e-3 and np.ptp(link) > 0.15  # still, then at the block

    def changed(a: np.ndarray, b: np.ndarray) -> int:
        """Pixels that changed by more than the video's compression does."""
        return int((np.abs(a.astype(int) - b.astype(int)).max(axis=2) > 60).sum())

    # the pictures follow the log: alike while the link is still, not once it has moved
    assert changed(frames[1], frames[0]) < 20
    assert changed(frames[-1], frames[0]) > 500


@pytest.mark.slow
def test_hil_render_draws_a_walk(walk_run: Path, tmp_path: Path) -> None:
    strip, gif = tmp_path / "walk.png", tmp_path / "walk.gif"
    assert main(["render", str(walk_run), "--out", str(strip), "--video", str(gif)]) == 0
    assert _png(strip).std() > 10
    from PIL import Image

    with Image.open(gif) as video:
        assert video.n_frames == int(np.ceil(load_run(walk_run).time_s[-1] * VIDEO_FPS))


def test_the_step_on_object_instants_are_the_papers_at_the_plans_step() -> None:
    from hil.output.rundir import RunData
    from hil.robots import get_experiment

    experiment = get_experiment(STEP_ON_OBJECT)
    singles = [s for s in experiment.pattern.timeline.segments if s.kind.value == "single_support"]
    lift_off = singles[experiment.object_footstep].start_tick * experiment.pattern.dt_s
    run = RunData(
        Path("."), {"time_s": np.arange(0, 9, 0.005)}, {"experiment": STEP_ON_OBJECT},
        {"experiment_start_s": 0.0}, (), ("",),
    )  # fmt: skip
    instants = default_instants(run)
    assert instants[0] == pytest.approx(lift_off)
    assert np.diff(instants) == pytest.approx(np.diff(PAPER_FIG8_S))


def test_without_pyopengl_hil_render_names_what_to_install(
    testbed_run: Path, tmp_path: Path
) -> None:
    shadow = tmp_path / "no_opengl" / "OpenGL"
    shadow.mkdir(parents=True)
    (shadow / "__init__.py").write_text("raise ImportError('No module named OpenGL')\n")
    env = {
        **os.environ,
        "PYTHONPATH": f"{shadow.parent}{os.pathsep}{os.environ.get('PYTHONPATH', '')}",
    }
    done = subprocess.run(
        [sys.executable, "-m", "hil", "render", str(testbed_run), "--out", str(tmp_path / "x.png")],
        env=env, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert done.returncode == 2, done.stderr
    assert GL_MISSING in done.stderr
    assert not (tmp_path / "x.png").exists()
