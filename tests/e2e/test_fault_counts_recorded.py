"""A run records what the emulator says its injected faults did (summary.json), so a rehearsal
shows that every fault it asked for really happened."""

from __future__ import annotations

from pathlib import Path

from tests.support.rig import hil_run


def test_the_summary_holds_the_emulators_fault_counts(tmp_path: Path) -> None:
    run = hil_run(
        tmp_path,
        "impact",
        "--duration",
        "1.5",
        "--inject",
        "dropped_reply@0.5",
        "--inject",
        "noisy_encoder@1.0+0.1",
    )
    counts = run.summary["emulator_fault_counts"]
    assert counts["scenario_faults_started"] == [0, 1]
    assert counts["dynamixel"]["replies_dropped"] == 1
    (encoder,) = counts["encoders"].values()
    assert encoder["noisy_samples"] == 20  # 0.1 s of 5 ms SYNCs
