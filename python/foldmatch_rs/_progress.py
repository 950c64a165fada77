"""The progress bar of :func:`foldmatch_rs.fit` (``progress=True``): tqdm's when tqdm is
installed, else one line on stderr rewritten in place. It is a callback chained before the
user's, so both work together."""

from __future__ import annotations

import sys
import time
from typing import Any, Callable, Optional

Callback = Callable[[dict[str, Any]], Optional[bool]]


def wanted(progress: Optional[bool]) -> bool:
    """``progress`` as given, or (``None``) on only when stderr is a terminal."""
    if progress is not None:
        return bool(progress)
    isatty = getattr(sys.stderr, "isatty", None)
    return bool(isatty and isatty())


class _Line:
    """A minimal bar, ``fit  45/100 [#########...........] 1.2 s  mean step 3.1e-04`` (the
    iteration's mean vertex displacement, in scan diagonals), redrawn at most ten times a
    second and at the end."""

    WIDTH = 24

    def __init__(self, total: int) -> None:
        self.total = total
        self.start = time.monotonic()
        self.drawn = 0.0
        self.n = 0
        self.shown = 0
        self.step = float("nan")

    def update(self, n: int, total: int, step: float) -> None:
        self.n, self.total, self.step = n, total, step
        now = time.monotonic()
        if now - self.drawn >= 0.1 or n >= total:
            self.drawn = now
            self.draw(now)

    def draw(self, now: float) -> None:
        filled = self.WIDTH * self.n // max(self.total, 1)
        bar = "#" * filled + "." * (self.WIDTH - filled)
        sys.stderr.write(
            f"\rfit {self.n:>{len(str(self.total))}}/{self.total} [{bar}] "
            f"{now - self.start:.1f} s  mean step {self.step:.1e}"
        )
        sys.stderr.flush()
        self.shown = self.n

    def close(self) -> None:
        if self.n:
            if self.shown != self.n:
                self.draw(time.monotonic())
            sys.stderr.write("\n")
            sys.stderr.flush()


class _Tqdm:
    def __init__(self, total: int) -> None:
        from tqdm.auto import tqdm

        self.bar = tqdm(total=total, desc="fit", unit="it", file=sys.stderr, leave=True)

    def update(self, n: int, total: int, step: float) -> None:
        if self.bar.total != total:
            self.bar.total = total
        self.bar.set_postfix_str(f"mean step {step:.1e}", refresh=False)
        self.bar.update(n - self.bar.n)

    def close(self) -> None:
        self.bar.close()


class Bar:
    """A progress bar fed by the fit's callback: ``with Bar(total, user) as cb: fit(cb)``."""

    def __init__(self, total: int, user: Optional[Callback]) -> None:
        try:
            self.shown: Any = _Tqdm(total)
        except ImportError:
            self.shown = _Line(total)
        self.user = user

    def __call__(self, info: dict[str, Any]) -> Optional[bool]:
        self.shown.update(info["iteration"], info["iterations"], info["mean_displacement"])
        return None if self.user is None else self.user(info)

    def __enter__(self) -> Bar:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.shown.close()
