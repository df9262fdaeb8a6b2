"""A session on the in-process setup: one run as `hil run EXPERIMENT` makes it (directory name,
record, plot, printed result), and the paper's whole comparison with its report."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from hil.config import load_config
from hil.experiments import IMPACT
from hil.session import Session, Setup, run_comparison
from hil.vocabulary import ControllerChoice, ControllerKind

CONFIG = load_config()


def _session(tmp_path: Path, **kwargs: object) -> Session:
    return Session(CONFIG, Setup.IN_PROCESS, out_root=tmp_path, quiet=True, **kwargs)


def test_one_run_writes_its_directory_and_says_what_it_drove(tmp_path: Path, capsys) -> None:
    session = _session(tmp_path, json_output=True)
    choice = ControllerChoice(ControllerKind.GC_LQR_DOB, 0.5)
    result = session.run_one(IMPACT, choice, duration_s=1.5)
    assert result.ok
    assert result.out_dir.name.endswith("-impact-gc-lqr-dob-k0.5")
    for name in ("log.csv", "events.jsonl", "summary.json", "meta.json", "plot.png"):
        assert (result.out_dir / name).is_file(), name
    meta = json.loads((result.out_dir / "meta.json").read_text())
    assert meta["controller_label"] == "gc+lqr+dob (Kdist 0.5)"
    assert meta["bus"]["in_process"] is True and meta["clock"] == "lockstep"
    assert meta["config"]["controller"]["kdist"] == CONFIG.controller.kdist
    printed = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert printed["termination"] == "completed"
    assert printed["first_peak_rad"] == pytest.approx(result.metrics["first_peak_rad"])


def test_a_configured_literal_reading_is_named_in_the_label_and_the_directory(
    tmp_path: Path,
) -> None:
    config = CONFIG.changed("controller", composition="literal")
    session = Session(config, Setup.IN_PROCESS, out_root=tmp_path, quiet=True, plots=False)
    choice = ControllerChoice(ControllerKind.GC_LQR_DOB, 1.0)
    result = session.run_one(IMPACT, choice, duration_s=0.2)
    assert result.out_dir.name.endswith("-gc-lqr-dob-k1-literal")
    summary = json.loads((result.out_dir / "summary.json").read_text())
    assert summary["controller_label"] == "gc+lqr+dob (Kdist 1), literal (25)"


@pytest.mark.slow
def test_the_comparison_runs_the_plan_and_checks_every_relation(tmp_path: Path, capsys) -> None:
    outcome = run_comparison(_session(tmp_path, plots=False), long_runs=False)
    assert outcome.incomplete is None
    runs = sorted(p.name for p in outcome.root.iterdir() if p.is_dir())
    assert len(runs) == 12 and "contact-gc-lqr-dob-k1-literal" in runs
    relations = outcome.report.relations
    assert len(relations) == 13 and all(r.holds is not None for r in relations)
    for name in ("report.md", "report.json", "fig5_contact.png", "fig6_impact.png"):
        assert (outcome.root / name).is_file()
    assert "The paper's relations" in capsys.readouterr().out
