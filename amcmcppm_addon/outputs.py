"""Optional files the engine writes while it renders (``scene.amcmcppm`` Statistics Output).

* statistics: one JSON line per pass, the core's per-pass dict plus the view layer
  and frame, appended to ``stats_path``;
* snapshots: at each requested elapsed time (the core's ``elapsed_s``), the image
  of the first pass that ends at or after it (or the final image, for times up to the time
  limit that the render ended just short of), as ``snapshot_<seconds>s.exr`` in
  ``snapshot_dir``, indexed in ``snapshots.jsonl`` there.  These feed
  error-versus-time curves (``shared/docs/testing.md`` section 3).
"""
from __future__ import annotations

import json
import os

from .exr import write_exr


class RenderOutputs:
    """Opened before the render (so bad paths fail early), fed every pass, closed after."""

    def __init__(self, stats_path="", snapshot_times=(), snapshot_dir="", tags=None):
        self.tags = dict(tags or {})
        self.stats_file = None
        self.pending = sorted(snapshot_times)
        self.snapshot_dir = snapshot_dir
        self.written = []               # (time, path) of the snapshots written
        if self.pending and not snapshot_dir:
            raise ValueError("snapshot times are set but the snapshot folder is empty")
        try:
            if self.pending:
                what = f"the Snapshot Folder '{snapshot_dir}'"
                os.makedirs(snapshot_dir, exist_ok=True)
                if not os.access(snapshot_dir, os.W_OK):
                    raise PermissionError(13, "not writable")
            if stats_path:
                what = f"the Statistics File '{stats_path}'"
                os.makedirs(os.path.dirname(os.path.abspath(stats_path)), exist_ok=True)
                self.stats_file = open(stats_path, "a", encoding="utf-8")
        except OSError as e:
            raise ValueError(f"cannot write {what} ({e.strerror or e}); change it in Render Properties > "
                             "Statistics Output, or clear it") from None

    def on_pass(self, result):
        """Record the last pass of a core ``RenderResult``."""
        stats = result.stats[-1]
        if self.stats_file is not None:
            self.stats_file.write(json.dumps({**stats, **self.tags}) + "\n")
            self.stats_file.flush()
        while self.pending and stats["elapsed_s"] >= self.pending[0]:
            self._snapshot(self.pending.pop(0), stats, result.image)

    def finish(self, result, time_limit):
        """After the render: snapshot times up to its time limit that no pass reached get the
        final image, unless the user stopped it.  The core ends at, or a little before, the
        limit (it skips a last pass that the limit would cut short), so without this a render
        run "until the last snapshot time" could miss that snapshot."""
        if result.interrupted or time_limit <= 0 or not result.stats:
            return
        while self.pending and self.pending[0] <= time_limit:
            self._snapshot(self.pending.pop(0), result.stats[-1], result.image)

    def _snapshot(self, t, stats, image):
        view = self.tags.get("view")
        name = f"snapshot_{t:011.3f}s{'_' + view if view else ''}.exr"
        path = os.path.join(self.snapshot_dir, name)
        write_exr(path, image)
        entry = {"time": t, "elapsed_s": stats["elapsed_s"], "pass": stats["pass"], "file": name, **self.tags}
        with open(os.path.join(self.snapshot_dir, "snapshots.jsonl"), "a", encoding="utf-8") as f:
            f.write(json.dumps(entry) + "\n")
        self.written.append((t, path))

    def close(self):
        if self.stats_file is not None:
            self.stats_file.close()
            self.stats_file = None
