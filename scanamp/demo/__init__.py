"""The demo room: ``scanamp demo`` end to end.

``pipeline`` (scene, captures and reconstructions through the methods registry, one
evaluation for all, amplification, animations), ``report`` (its figures and
``report.html``), ``amplify.toml`` (the demo's amplification recipe).

>>> from scanamp.demo import SCALES
>>> sorted(SCALES)
['default', 'full', 'test']
"""

from core.lazy import lazy_exports

_EXPORTS = {
    "run": "pipeline", "DemoSettings": "pipeline", "SCALES": "pipeline", "METHODS": "pipeline",
    "visible_from_above": "pipeline", "score": "pipeline", "canonical_mesh": "pipeline",
    "collider_proxy": "pipeline", "REPORT_FORMAT": "pipeline", "AMPLIFY_RECIPE": "pipeline",
    "figures": "report", "write_html": "report",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
