"""Progress of a batch: a tqdm bar on a terminal, one plain line per shot otherwise (farm logs); and
of one physics simulation's or planner's steps (``StepBar``: a bar on a terminal, otherwise a plain
line a minute while a simulation runs longer than that)."""

from __future__ import annotations

import sys
import time
from typing import Callable, TextIO


def shot_line(record: dict, done: int, total: int) -> str:
    """``[3/20] done       walk_01  1.23 s  (message)``"""
    width = len(str(total))
    line = f"[{done:>{width}}/{total}] {record['status']:<14} {record['name']}  {record['seconds']:.2f} s"
    if record.get("message"):
        line += f"  {record['message']}"
    return line


def _say(stream: TextIO, line: str) -> None:
    # One write with its newline: print() writes the newline apart, and a SIGTERM handled between
    # the two left the command's last line glued to this one in a farm's log.
    stream.write(line + "\n")
    stream.flush()


class Progress:
    """Reports each finished shot; a bar when ``stream`` is a terminal."""

    def __init__(self, total: int, stream: TextIO | None = None, bar: bool | None = None) -> None:
        self.total, self.done = total, 0
        self.stream = stream or sys.stderr
        use_bar = self.stream.isatty() if bar is None else bar
        self.bar = None
        if use_bar:
            from tqdm import tqdm

            self.bar = tqdm(total=total, unit="shot", file=self.stream, dynamic_ncols=True)

    def __call__(self, record: dict) -> None:
        self.done += 1
        line = shot_line(record, self.done, self.total)
        if self.bar is not None:
            self.bar.write(line, file=self.stream)
            self.bar.set_postfix_str(record["name"], refresh=False)
            self.bar.update(1)
        else:
            _say(self.stream, line)
        for warning in record.get("warnings", []):
            text = f"    warning: {warning}"
            if self.bar is not None:
                self.bar.write(text, file=self.stream)
            else:
                _say(self.stream, text)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


LINE_EVERY_S = 60.0  # a log's line while one simulation runs: a farm's stalled-task watchdog waits minutes


class StepBar:
    """``progress(k, steps)`` of a physics simulation (``passes.physics.run``) or of the attend
    planner (``vision.loop.run``); a call with a smaller ``k`` than the last starts the next simulation
    (another shot, or a shot simulated again). On a terminal, a tqdm bar. Off one (a farm's log), a
    plain line every ``every_s`` seconds (:data:`LINE_EVERY_S`) while a simulation runs, ``usdgaze:
    simulation 2: step 120 of 414 (29%), 61 s``: the whole 8.3 s stones walk takes half an hour, and a log (or a farm's
    stalled-task watchdog) silent that long cannot tell it from a hung process. A shot done within
    ``every_s`` writes nothing here; the command's one line per shot follows either way."""

    def __init__(self, stream: TextIO | None = None, bar: bool | None = None, desc: str = "simulation",
                 every_s: float | None = None, clock: Callable[[], float] = time.monotonic) -> None:
        self.stream, self.desc = stream or sys.stderr, desc
        self.on = self.stream.isatty() if bar is None else bar
        self.every_s, self.clock = LINE_EVERY_S if every_s is None else every_s, clock
        self.bar, self.last, self.runs = None, 0, 0
        self.started = self.said = 0.0

    def __call__(self, k: int, steps: int) -> None:
        new = self.runs == 0 or k < self.last
        self.last = k
        if new:
            self.runs += 1
            self.started = self.said = self.clock()
        if not self.on:
            now = self.clock()
            if not new and now - self.said >= self.every_s:
                self.said = now
                _say(self.stream, f"usdgaze: {self.desc} {self.runs}: step {k} of {steps} "
                                  f"({100.0 * k / max(steps, 1):.0f}%), {now - self.started:.0f} s")
            return
        if new:
            from tqdm import tqdm

            self.close()
            self.bar = tqdm(total=steps, unit="step", desc=f"{self.desc} {self.runs}", file=self.stream,
                            dynamic_ncols=True, leave=False)
        self.bar.update(k - self.bar.n)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None


def step_lines(name: str, what: str) -> StepBar | None:
    """A batch shot's ``StepBar`` for its log: a plain line a minute, ``usdgaze: NAME: WHAT 1: step ...``,
    while one of its simulations (``what``) runs longer (a farm task per shot, ``--task-index``, is
    otherwise one long silence); None on a terminal, where the batch's own bar is."""
    return None if sys.stderr.isatty() else StepBar(sys.stderr, bar=False, desc=f"{name}: {what}")
