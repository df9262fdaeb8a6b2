"""`hil render RUN_DIR`: the emulated robot drawn from a run's log with MuJoCo's offscreen
renderer - snapshots at chosen instants as one strip (the paper's Fig. 8 for the step onto the
object) and a short video.

    scene.py     the run's robot and world as a MuJoCo model, posed from the log
    drawing.py   the camera (a side view, as the paper's Fig. 8), the strip and the video

Rendering needs OpenGL: PyOpenGL (the `render` extra) and Mesa's EGL or OSMesa from the OS
(GL_MISSING says how). It runs in a process of its own (`hil render`, or `render_in_process`
for `hil run walking`'s report), which picks the backend before MuJoCo's GL is loaded:
MUJOCO_GL as set, else "egl".
"""

from __future__ import annotations

GL_MISSING = (
    "rendering needs OpenGL: PyOpenGL (pip install 'flexjoint-hil[render]') and Mesa's EGL "
    "(Debian/Ubuntu: apt-get install -y libegl1 libgl1-mesa-dri) or OSMesa (apt-get install "
    "-y libosmesa6, then MUJOCO_GL=osmesa)"
)
