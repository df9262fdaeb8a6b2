"""The paper's Fig. 8 drawn for `hil run walking`'s report: the step-on-object run of the
paper's controller (GC + LQR + DOB; another controller's if that one did not run), its robot
drawn at the Fig. 8 instants (hil/render/drawing.py) beside the report."""

from __future__ import annotations

import subprocess
from collections.abc import Sequence
from pathlib import Path

from hil.output.records import RunEntry
from hil.render.process import GlUnavailable, render_run_dir
from hil.vocabulary import ControllerKind

FIG8_RENDERED = "fig8_rendered.png"
STEP_ON_OBJECT = "step-on-object"


def rendered_fig8(root: Path, entries: Sequence[RunEntry]) -> tuple[list[Path], list[str]]:
    """(the strip written, or nothing; why not, or nothing) for a comparison's runs."""
    runs = [e for e in entries if e.experiment == STEP_ON_OBJECT and e.result.ticks > 1]
    if not runs:
        return [], []
    paper = str(ControllerKind.GC_LQR_DOB)
    entry = next((e for e in runs if e.choice.name == paper), runs[0])
    try:
        return render_run_dir(entry.result.out_dir, None, root / FIG8_RENDERED), []
    except (GlUnavailable, RuntimeError, OSError, subprocess.TimeoutExpired) as exc:
        return [], [f"{FIG8_RENDERED} (the robot drawn at Fig. 8's instants): {exc}"]
