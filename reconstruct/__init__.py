"""reconstruct: reconstruction from captures (virtual or real), and evaluation.

Shared rooms (imported by the method rooms, never the reverse):
:mod:`reconstruct.calibration`, :mod:`reconstruct.evaluation`,
:mod:`reconstruct.registration`, :mod:`reconstruct.surface`, :mod:`reconstruct.mvs`, and the
module :mod:`reconstruct.camera_files` (cameras from other tools' files).

One room per method: :mod:`reconstruct.laser`, :mod:`reconstruct.stereo` (with structured
light), :mod:`reconstruct.sfm`. reconstruct never imports data_synth: it runs on real
captures too. docs/architecture.md has the picture.

Public API here: :func:`evaluate` and :class:`EvaluationResult` (from
:mod:`reconstruct.evaluation.evaluate`; open3d and scipy load only when used).
"""

from reconstruct.evaluation.evaluate import EvaluationResult, evaluate

__all__ = ["evaluate", "EvaluationResult"]
