"""A progress bar with an ETA on stderr for long commands (tqdm), quiet when stderr is not a
terminal: then a command prints its own plain lines (`write`), as it always did.

    with Progress(total=12, unit="run", desc="comparison") as bar:
        bar.write("[1/12] contact: pid")   # above the bar on a terminal, a plain line otherwise
        bar.update_to(3.5, "impact: gc")   # fractional progress; the text beside the bar
"""

from __future__ import annotations

import sys
from typing import Any, TextIO


class Progress:
    def __init__(
        self,
        total: float,
        *,
        unit: str,
        desc: str,
        stream: TextIO | None = None,
        enabled: bool | None = None,
    ) -> None:
        """enabled: None decides by whether `stream` (stderr) is a terminal."""
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = self.stream.isatty() if enabled is None else enabled
        self._bar: Any = None
        if self.enabled:
            from tqdm import tqdm

            self._bar = tqdm(
                total=total,
                unit=unit,
                desc=desc,
                file=self.stream,
                dynamic_ncols=True,
                bar_format="{desc}: {percentage:3.0f}%|{bar}| {n:.1f}/{total:.0f} {unit} "
                "[{elapsed}<{remaining}{postfix}]",
            )

    def update_to(self, done: float, text: str | None = None) -> None:
        """Progress so far (in `unit`s, may be fractional), and optionally the text beside it."""
        bar = self._bar
        if bar is None:
            return
        bar.n = min(float(done), float(bar.total))
        if text is not None:
            bar.set_postfix_str(text, refresh=False)
        bar.refresh()

    def write(self, text: str, file: TextIO | None = None) -> None:
        """A line (to `file`, default the bar's stream) above the bar, or just the line."""
        out = file if file is not None else self.stream
        if self._bar is not None:
            self._bar.write(text, file=out)
        else:
            print(text, file=out, flush=True)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()
