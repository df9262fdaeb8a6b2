"""Issue 25, the front door: absurd but finite figures, and options that hung, are refused
before anything opens (exit 2, the key or option named); what waits, waits for its duration
and for Ctrl-C / SIGTERM.

Each case that used to hang runs `hil` in a child process with a timeout (and a memory limit:
`--config /dev/zero` read until memory ran out), so that a regression fails instead of hanging
the suite. The bad configurations point `hil run` at a running emulated testbed (`--attach`)
and read the device back with ROBOTIS's SDK: nothing was written to it.
"""

from __future__ import annotations

import json
import os
import resource
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from hil.cli import main
from hil.config import default_config_text, load_config
from tests.support.rig import (
    FACTORY_MAX_POSITION,
    FACTORY_RETURN_DELAY,
    emulated_testbed,
    read_device,
)

SAMPLE = default_config_text()
MEMORY_LIMIT_BYTES = 3 << 30  # a child reading without end dies of a MemoryError, not the machine


def _edited(*changes: tuple[str, str]) -> str:
    text = SAMPLE
    for old, new in changes:
        assert old in text, old
        text = text.replace(old, new, 1)
    return text


# figure -> (the file, what the error names); each was acted on or failed after the start
ABSURD_FIGURES = {
    "gravity moment 1e300": (
        _edited(("gravity_moment_kg_m = 0.63", "gravity_moment_kg_m = 1e300")),
        "gravity_moment_kg_m",
    ),
    "q_error 1e300": (_edited(("q_error = 10.0 ", "q_error = 1e300 ")), "q_error"),
    "r_input 1e-300": (_edited(("r_input = 1.0", "r_input = 1e-300")), "r_input"),
    "link inertia 1e-300": (
        _edited(("link_inertia_kg_m2 = 0.376", "link_inertia_kg_m2 = 1e-300")),
        "link_inertia_kg_m2",
    ),
    "stiffness 1e-300": (
        _edited(("stiffness_nm_per_rad = 2000.0", "stiffness_nm_per_rad = 1e-300")),
        "stiffness_nm_per_rad",
    ),
    "goal rate 1e300": (
        _edited(("max_goal_rate_rad_s = 2.0", "max_goal_rate_rad_s = 1e300")),
        "max_goal_rate_rad_s",
    ),
    "bus error ticks 1e9": (
        _edited(("bus_error_ticks = 3", "bus_error_ticks = 1000000000")),
        "bus_error_ticks",
    ),
    # every figure within its range, the corner together has no LQR (a singular matrix)
    "a design that does not exist": (
        _edited(
            ("stiffness_nm_per_rad = 2000.0", "stiffness_nm_per_rad = 100.0"),
            ("servo_gain_per_s = 10.0", "servo_gain_per_s = 0.1"),
            ("link_inertia_kg_m2 = 0.376", "link_inertia_kg_m2 = 0.001"),
            ("q_error = 10.0 ", "q_error = 1e-6 "),
            ("q_state = 1.0", "q_state = 0.0"),
            ("r_input = 1.0", "r_input = 1e6"),
        ),
        "q_error, q_state, r_input",
    ),
}


@pytest.fixture(scope="module")
def testbed():
    with emulated_testbed(load_config(), "contact") as emulator:
        yield emulator


def _untouched(emulator) -> bool:
    device = read_device(emulator.endpoints)
    return (device.return_delay_time, device.max_position_limit, device.torque_enabled) == (
        FACTORY_RETURN_DELAY,
        FACTORY_MAX_POSITION,
        0,
    )


@pytest.mark.timeout(120)
@pytest.mark.parametrize("case", sorted(ABSURD_FIGURES))
def test_an_absurd_figure_is_refused_before_the_first_byte(
    case: str, testbed, tmp_path: Path, capsys
) -> None:
    text, key = ABSURD_FIGURES[case]
    path = tmp_path / "testbed.toml"
    path.write_text(text)
    attach = json.dumps(testbed.endpoints)
    code = main(
        ["run", "contact", "--config", str(path), "--attach", attach, "--out", str(tmp_path)]
    )
    err = capsys.readouterr().err
    assert code == 2, err
    assert key in err and "configuration error" in err, err
    assert not list(tmp_path.glob("*/log.csv"))
    assert _untouched(testbed)


def _limit_memory() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT_BYTES, MEMORY_LIMIT_BYTES))


def _hil(*args: str, timeout: float = 60) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "hil", *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        preexec_fn=_limit_memory,
    )


@pytest.fixture(scope="module")
def endpoints_file(testbed, tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("attach") / "endpoints.json"
    path.write_text(json.dumps(testbed.endpoints))
    return path


@pytest.mark.timeout(120)
@pytest.mark.parametrize(
    ("args", "option"),
    [
        (["monitor", "--rate", "0.001", "--duration", "1"], "--rate"),  # slept 1000 s
        (["monitor", "--rate", "1e-300", "--duration", "1"], "--rate"),  # overflowed
        (["calibrate", "--seconds", "1e9"], "--seconds"),  # a MemoryError with the bus open
    ],
)
def test_an_option_that_hung_or_overflowed_is_refused_before_the_bus_opens(
    args: list[str], option: str, endpoints_file: Path, testbed
) -> None:
    proc = _hil(*args, "--attach", str(endpoints_file), timeout=60)
    assert proc.returncode == 2, proc.stderr
    assert option in proc.stderr and "Traceback" not in proc.stderr
    assert _untouched(testbed)


@pytest.mark.timeout(120)
def test_the_monitor_ends_at_its_duration_whatever_its_rate(endpoints_file: Path) -> None:
    """At 0.1 Hz a period is 10 s: the monitor slept all of it before it looked at its
    1 s duration."""
    started = time.monotonic()
    proc = _hil(
        "monitor", "--attach", str(endpoints_file), "--rate", "0.1", "--duration", "1", "--json"
    )
    elapsed = time.monotonic() - started
    assert proc.returncode == 0, proc.stderr
    assert len(proc.stdout.splitlines()) == 1  # the first sample, then the end of the second
    assert elapsed < 8.0, f"{elapsed:.1f} s for a 1 s monitor (a 10 s period slept whole)"


@pytest.mark.timeout(120)
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_the_monitor_ends_on_a_signal_during_its_wait(endpoints_file: Path, sig: int) -> None:
    process = subprocess.Popen(
        [sys.executable, "-m", "hil", "monitor", "--attach", str(endpoints_file), "--json"]
        + ["--rate", "0.1"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    try:
        assert json.loads(process.stdout.readline())["joints"]  # sampled; now 10 s of wait
        signalled = time.monotonic()
        process.send_signal(sig)
        _, err = process.communicate(timeout=30)
        elapsed = time.monotonic() - signalled
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    assert process.returncode == 0, err
    assert "left as found" in err
    assert elapsed < 5.0, f"{elapsed:.1f} s after the signal (the 10 s wait slept whole)"


@pytest.mark.timeout(120)
@pytest.mark.parametrize("what", ["/dev/zero", "fifo", "big"])
def test_a_configuration_that_is_no_file_of_text_is_refused_at_once(
    what: str, tmp_path: Path
) -> None:
    """/dev/zero was read until memory ran out, a FIFO waited for a writer for ever."""
    if what == "fifo":
        path = tmp_path / "config.fifo"
        os.mkfifo(path)
    elif what == "big":
        path = tmp_path / "big.toml"
        path.write_text(SAMPLE + "#" * (2 << 20) + "\n")
    else:
        path = Path(what)
    proc = _hil("run", "contact", "--config", str(path), "--out", str(tmp_path), timeout=60)
    assert proc.returncode == 2, proc.stderr
    assert str(path) in proc.stderr and "Traceback" not in proc.stderr
    assert "not a regular file" in proc.stderr or "bytes" in proc.stderr


@pytest.mark.faults
@pytest.mark.timeout(300)
def test_a_ctrl_c_at_any_moment_of_the_start_is_one_line_and_status_1(tmp_path: Path) -> None:
    """From the first imports to the loop: never a KeyboardInterrupt traceback."""
    outcomes = []
    for delay in (0.1, 0.25, 0.4, 0.6, 0.8, 1.0, 1.3, 1.7):
        process = subprocess.Popen(
            [sys.executable, "-m", "hil", "run", "impact", "--out", str(tmp_path), "--no-plots"],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
        )
        time.sleep(delay)
        process.send_signal(signal.SIGINT)
        _, err = process.communicate(timeout=120)
        outcomes.append((delay, process.returncode, err))
    for delay, code, err in outcomes:
        assert "Traceback" not in err, f"Ctrl-C at {delay} s:\n{err}"
        # 1: interrupted; 0: the run had already ended; -SIGINT: before Python was up
        assert code in (1, 0, -signal.SIGINT), (delay, code, err)
    assert any(code == 1 and "hil: interrupted" in err for _, code, err in outcomes)
