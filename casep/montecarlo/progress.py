"""Progress of a campaign on stderr, drawn by tqdm, counted in runs of the current stage.

A stage is one per-run method, or all batched linear methods together (one pass over the
runs); each stage gets its own tqdm line, left on screen when the stage ends. ``mode`` "bar":
tqdm's bar redrawn in place (terminals); "lines": tqdm's text as a plain line every `every`
seconds and at the end of each stage (logs, pipes: :class:`_Lines` turns tqdm's redraws into
lines); None: silent. Elapsed time and ETA are those of the whole campaign, not the stage.
"""

from __future__ import annotations

import shutil
import sys
import time
from collections.abc import Sequence
from typing import IO, Any

from tqdm import tqdm  # type: ignore[import-untyped]

__all__ = ["Progress", "progress_mode"]


class _StageBar(tqdm):
    """tqdm with the campaign's share done, elapsed time and ETA as format fields."""

    monitor_interval = 0  # no monitor thread: the bar is updated once per finished task

    def __init__(self, *args: Any, owner: Progress, **kwargs: Any) -> None:
        self._owner = owner
        super().__init__(*args, **kwargs)

    @property
    def format_dict(self) -> dict[str, Any]:
        d = super().format_dict
        d.update(self._owner.overall(int(d["n"])))
        return d


class _Lines:
    """A stream for tqdm that writes each redraw (``"\\r" + text``) as a line of its own."""

    def __init__(self, stream: IO[str]) -> None:
        self.stream = stream
        self.encoding = getattr(stream, "encoding", "utf-8")

    def write(self, text: str) -> None:
        line = text.replace("\r", "").rstrip()
        if line:
            self.stream.write(line + "\n")

    def flush(self) -> None:
        self.stream.flush()


class Progress:
    """Progress of `runs` runs through each of `stages` (their labels), shown as `mode` says.

    Call it with the number of runs just finished; :meth:`next_stage` between stages;
    :meth:`close` at the end or on interruption.
    """

    def __init__(self, runs: int, stages: Sequence[str], mode: str | None, every: float = 5.0) -> None:
        self.runs, self.stages, self.mode, self.every = runs, list(stages), mode, every
        self.stage = 0
        self.t0 = time.monotonic()
        self.bar: _StageBar | None = None

    def __call__(self, k: int) -> None:
        if self.mode is None:
            return
        if self.bar is None:
            self.bar = self._open(k)  # drawn at once with the first k runs
        else:
            self.bar.update(k)
        if self.bar.n >= self.runs:
            self.close()  # the stage's last line stays

    def next_stage(self) -> None:
        self.close()
        self.stage += 1

    def close(self) -> None:
        """End the current stage's line (also on interruption)."""
        if self.bar is not None:
            self.bar.close()
            self.bar = None

    def overall(self, done: int) -> dict[str, Any]:
        """The campaign's share done (``all_pct``, %), elapsed seconds and ETA (``all_eta``, text)."""
        frac = (self.stage * self.runs + done) / (len(self.stages) * self.runs)  # share of all work
        elapsed = time.monotonic() - self.t0
        # ETA = elapsed (1 - f) / f: the rest at the rate so far
        eta = f"{elapsed * (1 - frac) / frac:.0f} s" if frac > 0 else "-"
        return {"all_pct": 100.0 * frac, "all_elapsed": elapsed, "all_eta": eta}

    def _open(self, done: int) -> _StageBar:
        label = self.stages[self.stage].replace("{", "{{").replace("}", "}}")
        several = len(self.stages) > 1
        tail = ", {all_elapsed:.0f} s elapsed, ETA {all_eta}"
        if self.mode == "bar":
            which = f" (method {self.stage + 1} of {len(self.stages)})" if several else ""
            fmt = "|{bar:24}| " + label + " {n_fmt}/{total_fmt} runs" + which + tail
            # the terminal's size, 80 x 24 where it reports none (tqdm would then hide the bar)
            cols, rows = shutil.get_terminal_size()
            return _StageBar(total=self.runs, initial=done, bar_format=fmt, file=sys.stderr, mininterval=0,
                             miniters=1, ncols=cols, nrows=rows, owner=self)
        which = (f" (method {self.stage + 1} of {len(self.stages)}, {{all_pct:.0f}} % of all)" if several
                 else " ({all_pct:.0f} %)")
        fmt = "montecarlo: " + label + " {n_fmt}/{total_fmt} runs" + which + tail
        return _StageBar(total=self.runs, initial=done, bar_format=fmt, file=_Lines(sys.stderr),
                         mininterval=self.every, miniters=1, owner=self)


def progress_mode(progress: bool | None) -> str | None:
    """The mode of :class:`Progress`: True, the bar on a terminal and lines otherwise; False, none;
    None, the bar on a terminal only."""
    tty = sys.stderr.isatty()
    if progress is None:
        return "bar" if tty else None
    return ("bar" if tty else "lines") if progress else None
