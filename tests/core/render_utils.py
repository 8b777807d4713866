"""Render helper shared by the closed-form tests."""
from __future__ import annotations

import numpy as np

from core import RenderSettings, render


def finite_render(scene, **settings):
    """``core.render`` with one worker and ``settings``, checking every pass's image is finite."""
    def check(result):
        assert np.isfinite(result.image).all()
    return render(scene, RenderSettings(workers=1, **settings), on_iteration=check)
