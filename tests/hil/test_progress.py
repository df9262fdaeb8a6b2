"""The progress bar: a bar with an ETA on a terminal, plain lines and no bar otherwise."""

from __future__ import annotations

import fcntl
import io
import os
import pty
import select
import struct
import termios

from hil.output.progress import Progress


def test_without_a_terminal_there_is_no_bar_only_the_lines() -> None:
    stream = io.StringIO()
    with Progress(4, unit="runs", desc="comparison", stream=stream) as bar:
        assert not bar.enabled
        bar.write("[1/4] contact: pid")
        bar.update_to(2.5, "impact: gc")
    assert stream.getvalue() == "[1/4] contact: pid\n"


def test_on_a_terminal_the_bar_shows_progress_and_the_time_left() -> None:
    leader, follower = pty.openpty()
    fcntl.ioctl(follower, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 120, 0, 0))  # 120 columns
    try:
        with open(follower, "w", closefd=False) as terminal:
            with Progress(4, unit="runs", desc="comparison", stream=terminal) as bar:
                assert bar.enabled
                bar.update_to(1.0, "contact: gc")
                bar.update_to(2.0, "impact: pid")
                bar.write("a line above the bar")
            terminal.flush()
        shown = ""
        while select.select([leader], [], [], 0.5)[0]:  # everything the terminal got
            shown += os.read(leader, 65536).decode()
    finally:
        os.close(leader)
        os.close(follower)
    assert "comparison:  50%" in shown and "2.0/4 runs" in shown
    assert "<" in shown  # elapsed<remaining: the ETA
    assert "impact: pid" in shown and "a line above the bar" in shown
