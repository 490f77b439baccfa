"""Lets the legacy ``rps`` (PyPI 0.0.0) draw its figure under a current matplotlib.

Shipped unchanged with every exported folder (``comat export``, ``comat export --calibration``).
The legacy simulator draws each robot with ``patches.RegularPolygon(xy, 4, radius, orientation,
...)``; matplotlib 3.10 made ``radius`` and ``orientation`` keyword-only, so the figure (on by
default, as the Robotarium wants) failed with ``RegularPolygon.__init__() takes 3 positional
arguments but 5 were given``. :func:`fix_legacy_drawing` gives the legacy module a
``RegularPolygon`` that accepts the old positional call; it changes nothing where the call already
works (an older matplotlib, V2, the Robotarium's own servers). Imports: matplotlib, rps and the
standard library only.
"""

import inspect
import types


def fix_legacy_drawing():
    """Adapt the legacy rps's drawing call if this matplotlib needs it; True when it did."""
    try:
        from matplotlib import patches
        from rps import robotarium_abc
    except ImportError:  # no matplotlib, or an rps without the legacy module: nothing to adapt
        return False
    drawing = getattr(robotarium_abc, "patches", None)
    radius = inspect.signature(patches.RegularPolygon.__init__).parameters.get("radius")
    if drawing is None or radius is None or radius.kind is not inspect.Parameter.KEYWORD_ONLY:
        return False

    class RegularPolygon(patches.RegularPolygon):
        """matplotlib's RegularPolygon taking radius and orientation by position, as legacy rps calls it."""

        def __init__(self, xy, numVertices, radius=5, orientation=0, **kwargs):
            super().__init__(xy, numVertices, radius=radius, orientation=orientation, **kwargs)

    names = {name: getattr(drawing, name) for name in dir(drawing) if not name.startswith("_")}
    robotarium_abc.patches = types.SimpleNamespace(**{**names, "RegularPolygon": RegularPolygon})
    return True
