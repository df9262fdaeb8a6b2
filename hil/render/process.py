"""The drawing of a run in a process of its own (`python -m hil.render`): MuJoCo reads
MUJOCO_GL once, when it is first imported, and the process that asks for a picture (the CLI,
a session writing its report) has imported it long before."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path

from hil.render import GL_MISSING

GL_UNAVAILABLE_EXIT = 3  # hil/render/__main__.py's


class GlUnavailable(RuntimeError):
    """No OpenGL backend could be opened (the message names what to install)."""


def render_run_dir(
    run_dir: Path,
    times_s: Sequence[float] | None,
    strip: Path,
    video: Path | None = None,
    timeout_s: float = 600.0,
) -> list[Path]:
    """The strip (and video) of a run directory, drawn by `python -m hil.render`; the files
    written. GlUnavailable without OpenGL; RuntimeError with the drawing's error otherwise."""
    command = [sys.executable, "-m", "hil.render", str(run_dir), "--out", str(strip)]
    if times_s:
        command += ["--at", *(repr(float(t)) for t in times_s)]
    if video is not None:
        command += ["--video", str(video)]
    env = {**os.environ}
    env.setdefault("MUJOCO_GL", "egl")
    done = subprocess.run(command, env=env, capture_output=True, text=True, timeout=timeout_s)
    if done.returncode == GL_UNAVAILABLE_EXIT:
        raise GlUnavailable(done.stderr.strip() or GL_MISSING)
    if done.returncode != 0:
        raise RuntimeError(f"drawing {run_dir} failed: {done.stderr.strip()[-2000:]}")
    return [Path(line) for line in done.stdout.splitlines() if line.strip()]
