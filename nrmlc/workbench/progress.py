"""Progress of a batch of jobs on stderr: frames done, runs done, speed and time left."""
from __future__ import annotations

import sys
import time

#: Seconds between plain progress lines when stderr is not a terminal.
PROGRESS_INTERVAL = 30.0


class Progress:
    """Frames done of a batch of jobs: a tqdm bar on a terminal, else a plain line
    every :data:`PROGRESS_INTERVAL` seconds (runs done/total, frames, fps, ETA)."""

    def __init__(self, total_frames: int, n_jobs: int, enabled: bool = True, stream=None,
                 interval: float = PROGRESS_INTERVAL) -> None:
        self.stream = sys.stderr if stream is None else stream
        self.total, self.n_jobs, self.interval = int(total_frames), int(n_jobs), float(interval)
        self.frames = self.jobs = 0
        self.start = self.last = time.monotonic()
        self.enabled = enabled
        self.bar = None
        if enabled and getattr(self.stream, "isatty", lambda: False)():
            from tqdm import tqdm

            self.bar = tqdm(total=self.total, unit="frame", desc=f"{n_jobs} runs", file=self.stream)
        elif enabled:
            self._line("started")

    def _line(self, what: str) -> None:
        elapsed = time.monotonic() - self.start
        rate = self.frames / elapsed if elapsed > 0 else 0.0
        eta = f", ETA {(self.total - self.frames) / rate / 60:.1f} min" if rate > 0 and self.frames < self.total else ""
        print(f"[runs] {what}: {self.jobs}/{self.n_jobs} runs, {self.frames}/{self.total} frames, "
              f"{rate:.0f} frames/s, {elapsed / 60:.1f} min{eta}", file=self.stream, flush=True)

    def update(self, frames: int, title: str = "") -> None:
        self.frames += int(frames)
        self.jobs += 1
        if self.bar is not None:
            self.bar.update(int(frames))
            self.bar.set_postfix_str(title, refresh=False)
        elif self.enabled and time.monotonic() - self.last >= self.interval:
            self.last = time.monotonic()
            self._line("progress")

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
        elif self.enabled:
            self._line("done" if self.jobs == self.n_jobs else "stopped")
