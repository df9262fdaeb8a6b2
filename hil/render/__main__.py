"""`python -m hil.render RUN_DIR [--at T ...] --out PNG [--video FILE]`: the drawing in a process
of its own, MUJOCO_GL chosen before MuJoCo is imported (`hil render` and `hil run walking`'s
report start it: hil/render/process.py). Prints the files written, one a line; exit
GL_UNAVAILABLE_EXIT when no OpenGL backend opens (the message on stderr)."""

from __future__ import annotations

import os
import sys

os.environ.setdefault("MUJOCO_GL", "egl")  # before anything imports MuJoCo's GL

import argparse
from pathlib import Path

from hil.render.process import GL_UNAVAILABLE_EXIT


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m hil.render")
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--at", type=float, nargs="+")
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--video", type=Path)
    args = parser.parse_args(argv)
    from hil.output.rundir import load_run
    from hil.render.drawing import GlUnavailable, render_run

    try:
        written = render_run(load_run(args.run_dir), args.at, args.out, args.video)
    except GlUnavailable as exc:
        print(exc, file=sys.stderr)
        return GL_UNAVAILABLE_EXIT
    for path in written:
        print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
