"""``scene.amcmcppm`` (a PropertyGroup) -> :class:`core.RenderSettings`.

Property names equal the dataclass field names (see ``properties.py``), so the
mapping is one loop; ``RenderSettings`` validates the values and raises a
``ValueError`` naming the field when they cannot be rendered.
"""
import re

from ...core.settings import RenderSettings
from ..properties import CORE_SETTING_NAMES


def render_settings_from(props, **overrides) -> RenderSettings:
    """The core settings for the PropertyGroup ``props``, with optional field overrides; the
    bounce limits are Cycles' when ``props.light_paths_from_cycles`` (``light_path_limits``)."""
    values = {name: _decimal(getattr(props, name)) for name in CORE_SETTING_NAMES}
    values.update(props.light_path_limits()[0])
    values.update(overrides)
    try:
        return RenderSettings(**values)
    except ValueError as e:
        # (the panel's names for the fields the message names: "RenderSettings.passes" and
        # "time_limit" -> 'Passes' and 'Time Limit')
        labels = {name: props.bl_rna.properties[name].name for name in CORE_SETTING_NAMES
                  if name in props.bl_rna.properties}

        def label(m):
            name = m[1] or m[2]
            return f"'{labels[name]}'" if name in labels else m[0]
        named = r"RenderSettings\.(\w+)|\b([a-z]+(?:_[a-z0-9]+)+)\b"
        raise ValueError(re.sub(named, label, str(e))) from None


def _decimal(value):
    """A FloatProperty's float32 value as the decimal the panel shows (7 significant digits): its
    limits, stored in float32, fall just outside the core's (1e-4 is 9.99999975e-05)."""
    return float(f"{value:.7g}") if isinstance(value, float) else value


def parse_snapshot_times(text):
    """Sorted positive seconds from a comma-separated string ("1, 2,4" -> [1.0, 2.0, 4.0]).

    Raises ``ValueError`` with a readable message for anything else.
    """
    times = []
    for part in text.replace(";", ",").split(","):
        part = part.strip()
        if not part:
            continue
        try:
            t = float(part)
        except ValueError:
            raise ValueError(f"snapshot time {part!r} is not a number") from None
        if not t > 0 or t == float("inf"):
            raise ValueError(f"snapshot time {part!r} must be a positive number of seconds")
        times.append(t)
    return sorted(set(times))
