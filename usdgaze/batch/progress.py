"""Progress of a batch: a tqdm bar on a terminal, one plain line per shot otherwise (farm logs); and
of one physics simulation's steps (``StepBar``: a bar on a terminal, nothing otherwise)."""

from __future__ import annotations

import sys
from typing import TextIO


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


class StepBar:
    """``progress(k, steps)`` of a physics simulation (``passes.physics.run``) or of the attend
    planner (``vision.loop.run``) as a tqdm bar on a terminal; a call with a smaller ``k`` than the last starts the next simulation (another shot, or
    a shot simulated again) on the same bar. Off a terminal it writes nothing: a farm's log gets the
    command's one line per shot."""

    def __init__(self, stream: TextIO | None = None, bar: bool | None = None, desc: str = "simulation") -> None:
        self.stream, self.desc = stream or sys.stderr, desc
        self.on = self.stream.isatty() if bar is None else bar
        self.bar, self.last, self.runs = None, 0, 0

    def __call__(self, k: int, steps: int) -> None:
        if not self.on:
            return
        if self.bar is None or k < self.last:
            from tqdm import tqdm

            self.close()
            self.runs += 1
            self.bar = tqdm(total=steps, unit="step", desc=f"{self.desc} {self.runs}", file=self.stream,
                            dynamic_ncols=True, leave=False)
        self.bar.update(k - self.bar.n)
        self.last = k

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None
