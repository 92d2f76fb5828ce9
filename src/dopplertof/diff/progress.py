"""Progress of the iterative solvers of :mod:`dopplertof.diff` (the fit, fit_captures)."""

from __future__ import annotations


class IterationProgress:
    """An iterative solver's progress: a tqdm bar titled ``desc`` on a terminal
    (``progress`` True, or None with stderr a terminal), else (None) ``line(entry)`` on
    stderr per iteration, or nothing (False). ``postfix(entry)``: the bar's postfix
    (a dict), if any."""

    def __init__(self, progress, iterations: int, desc: str, line, postfix=None):
        import sys

        self.line, self.postfix = line, postfix
        self.bar, self.lines = None, progress is None and not sys.stderr.isatty()
        if progress or (progress is None and sys.stderr.isatty()):
            from tqdm import tqdm

            self.bar = tqdm(total=iterations, desc=desc, unit="it", leave=False)

    def update(self, entry: dict) -> None:
        import sys

        if self.bar is not None and entry["iteration"] > 0:
            self.bar.update(1)
            if self.postfix is not None:
                self.bar.set_postfix(**self.postfix(entry))
        if self.lines:
            print(self.line(entry), file=sys.stderr, flush=True)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
