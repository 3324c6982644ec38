"""Progress display of a run: tqdm when installed (``tqdm.auto``: the
widget in Jupyter, a text bar in a terminal), else one line on stderr
rewritten in place. Fed by the run with the simulated time, at most every
0.1 s of wall time."""

from __future__ import annotations

import sys
import time
from typing import Any, Callable, Optional, Union

#: What ``Scenario.run(progress=...)`` takes: False/None (no display),
#: True (a bar) or a callable ``progress(t, t0, t_end)``.
ProgressArg = Union[bool, None, Callable[[float, float, float], Any]]


class Progress:
    """A progress bar over the simulated time of one run [s]."""

    def __init__(self, name: str, file: Any = None, use_tqdm: Optional[bool] = None) -> None:
        self.name = name
        self.file = file if file is not None else sys.stderr
        self.bar: Any = None
        self.span: Optional[tuple] = None
        self.started = time.perf_counter()
        self.last_t: Optional[float] = None
        self.tqdm: Any = None
        if use_tqdm is not False:
            try:
                from tqdm.auto import tqdm

                self.tqdm = tqdm
            except ImportError:
                self.tqdm = None

    def __call__(self, t: float, t0: float, t_end: float) -> None:
        """The run reached simulated time ``t`` of ``[t0, t_end]``."""
        span = max(t_end - t0, 0.0)
        done = min(max(t - t0, 0.0), span)
        self.last_t = t
        if self.tqdm is not None:
            if self.bar is None:
                self.bar = self.tqdm(total=span, desc=self.name, unit="s",
                                     bar_format="{l_bar}{bar}| t = {n:.4g}/{total:.4g} s "
                                                "[{elapsed}<{remaining}]",
                                     file=self.file, leave=True)
            self.bar.update(done - self.bar.n)
            return
        self.span = (t0, t_end)
        frac = done / span if span > 0 else 1.0
        width = 30
        filled = int(round(frac * width))
        elapsed = time.perf_counter() - self.started
        self.file.write(f"\r{self.name}: [{'#' * filled}{'.' * (width - filled)}] "
                        f"t = {t:.4g}/{t_end:.4g} s ({100 * frac:3.0f} %), {elapsed:.1f} s")
        self.file.flush()

    def close(self) -> None:
        """End the display (the bar stays where the run ended)."""
        if self.bar is not None:
            self.bar.close()
            self.bar = None
        elif self.span is not None:
            self.file.write("\n")
            self.file.flush()


def make(progress: ProgressArg, name: str) -> Optional[Callable[[float, float, float], Any]]:
    """The callable the run feeds: None, a :class:`Progress` or the user's."""
    if progress is None or progress is False:
        return None
    if progress is True:
        return Progress(name)
    if callable(progress):
        return progress
    raise TypeError(f"progress: expected True, False or a callable (t, t0, t_end), "
                    f"not {type(progress).__name__}")
