"""Plots of one run (filled in below)."""

from __future__ import annotations

from pathlib import Path

from hil.experiments import Experiment


def plot_run(out_dir: Path, experiment: Experiment) -> None:
    return None
