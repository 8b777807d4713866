"""Core images -> Blender's render result; progress and statistics in Blender's header.

The core's image is (H, W, 4) float32 linear RGBA with the *top* row first and
covers the render window (the border box at the percentage-scaled resolution);
Blender's ``RenderPass.rect`` wants the *bottom* row first.  Pixels are pushed
with one ``foreach_set`` of a contiguous float32 buffer (about 2 ms for 1080p;
assigning ``rect`` an array is ~500x slower, ``shared/docs/blender.md`` 1).
"""
from __future__ import annotations

import time

import numpy as np


def to_rect(image, width, height, channels=4):
    """Flat float32 buffer of ``image`` (top row first; (H, W, channels), or (H, W) for one
    channel) for a ``width`` x ``height`` pass.

    Returns ``(buffer, problems)``: ``problems`` lists what had to be repaired (a size
    mismatch is cropped or padded with black, non-finite values become 0), so a
    broken image never reaches Blender as NaN.
    """
    img = np.asarray(image, np.float32)
    if img.ndim == 2 and channels == 1:
        img = img[:, :, None]
    problems = []
    if img.shape[:2] != (height, width) or img.ndim != 3 or img.shape[2] != channels:
        problems.append(f"image of shape {img.shape} did not match the {width}x{height} render result")
        fitted = np.zeros((height, width, channels), np.float32)
        if img.ndim == 3 and img.shape[2] == channels:
            h, w = min(height, img.shape[0]), min(width, img.shape[1])
            fitted[:h, :w] = img[:h, :w]
        img = fitted
    bottom_up = np.ascontiguousarray(img[::-1], np.float32)
    bad = ~np.isfinite(bottom_up)
    if bad.any():
        problems.append(f"{int(bad.any(axis=2).sum())} pixels were not finite and were set to 0")
        bottom_up[bad] = 0.0
    return bottom_up.reshape(-1), problems


class ResultWriter:
    """Owns one ``begin_result``/``end_result`` pair and pushes images into its Combined pass.

    Use as a context manager; the result is always ended (never cancelled), so an
    interrupted render keeps the image pushed last.
    """

    def __init__(self, engine, layer_name, view=""):
        self.engine = engine
        self.layer_name = layer_name
        self.view = view                # Stereoscopy's view this result is of ("" with none)
        self.result = None
        self.width = self.height = 0
        self.problems = []

    def __enter__(self):
        e = self.engine
        # Blender clamps the rectangle to the border box and makes it the result's origin.
        self.result = e.begin_result(0, 0, e.resolution_x, e.resolution_y, layer=self.layer_name,
                                     view=self.view)
        if self.result is None:
            raise RuntimeError("Blender returned no render result to write into")
        self.width, self.height = self.result.resolution_x, self.result.resolution_y
        return self

    def push(self, image):
        """Write ``image`` into the Combined pass and show it."""
        rect, problems = to_rect(image, self.width, self.height)
        for p in problems:
            if p not in self.problems:
                self.problems.append(p)
        self.result.layers[0].passes["Combined"].rect.foreach_set(rect)
        self.engine.update_result(self.result)

    def write_data(self, images):
        """Write the data passes ``images`` (Blender's pass name -> (H, W[, C]) top row first)
        into the passes of those names the result has (``update_render_passes`` registered)."""
        passes = self.result.layers[0].passes
        for name, image in images.items():
            target = passes.get(name)
            if target is None:
                continue
            rect, problems = to_rect(image, self.width, self.height, target.channels)
            for p in problems:
                if p not in self.problems:
                    self.problems.append(f"{name} pass: {p}")
            target.rect.foreach_set(rect)
        if images:
            self.engine.update_result(self.result)

    def add_metadata(self, fields):
        """Add ``fields`` ({key: value}) to the render's metadata (written into EXR files): to the
        engine's whole result, as Cycles stamps its view layers' (a result from ``begin_result``
        keeps none)."""
        if not fields:
            return
        whole = self.engine.get_result()
        for key, value in fields.items():
            whole.stamp_data_add_field(key, value)

    def push_black(self):
        image = np.zeros((self.height, self.width, 4), np.float32)
        image[:, :, 3] = 1.0
        self.push(image)

    def __exit__(self, *exc):
        self.engine.end_result(self.result)
        self.result = None
        return False


class PushSchedule:
    """When to push the image: after passes 1, 3, 7, ... (batches doubling) until pushes are
    about ``interval`` seconds apart, then about once per ``interval``."""

    def __init__(self, interval=1.0, clock=time.perf_counter):
        self.interval = interval
        self.clock = clock
        self.batch = 1                  # passes between pushes
        self.since = 0                  # passes since the last push
        self.last = clock()

    def due(self) -> bool:
        """Call once per finished pass; True when this pass's image should be pushed."""
        self.since += 1
        now = self.clock()
        if self.since < self.batch and now - self.last < self.interval:
            return False
        if now - self.last < self.interval:
            self.batch *= 2
        self.since = 0
        self.last = now
        return True


def format_duration(seconds) -> str:
    seconds = max(0.0, float(seconds))
    if seconds < 60:
        return f"{seconds:.0f} s" if seconds >= 10 else f"{seconds:.1f} s"
    m, s = divmod(int(round(seconds)), 60)
    h, m = divmod(m, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m}:{s:02d}"


def time_left(settings, passes_done, elapsed):
    """Seconds left by the pass count and/or time limit, or None when unbounded."""
    bounds = []
    if settings.passes and passes_done:
        bounds.append((settings.passes - passes_done) * elapsed / passes_done)
    if settings.time_limit:
        bounds.append(settings.time_limit - elapsed)
    return max(0.0, min(bounds)) if bounds else None


def progress_fraction(settings, passes_done, elapsed) -> float:
    f = 0.0
    if settings.passes:
        f = max(f, passes_done / settings.passes)
    if settings.time_limit:
        f = max(f, elapsed / settings.time_limit)
    return float(min(1.0, f))


def stats_line(settings, stats, photons_total) -> str:
    """One header line from the core's per-pass statistics dict."""
    p = stats["pass"]
    parts = [f"Pass {p}/{settings.passes}" if settings.passes else f"Pass {p}",
             f"Photons {photons_total:,}"]
    if stats.get("method") == "amcmcppm":
        parts += [f"Acceptance {stats['acceptance_rate']:.2f}", f"Mutation {stats['mutation_size']:.3g}"]
    parts.append(f"Visible {stats['visible_fraction']:.3g}")
    left = time_left(settings, p, stats["elapsed_s"])
    parts.append(f"Time {format_duration(stats['elapsed_s'])}")
    if left is not None:
        parts.append(f"Left {format_duration(left)}")
    return " | ".join(parts)
