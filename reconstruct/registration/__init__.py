"""reconstruct.registration: rigid registration: a scan to a reference from any starting
frame.

Modules: ``rigid``.

Every name below is importable from the room (``from reconstruct.registration import
NAME``), loaded on first use.
"""

from core.lazy import lazy_exports

_EXPORTS = {
    "ALIGN_METHODS": "rigid",
    "LOW_FITNESS": "rigid",
    "Registration": "rigid",
    "register": "rigid",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
