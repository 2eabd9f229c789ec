"""core.runs: how a run writes its results.

- :mod:`core.runs.outputs` output folders that never destroy: where a command may write
  and the running command's declared output (the manifest itself is :mod:`core.files`'s);
- :mod:`core.runs.stages` pipeline stages, each skipped when its inputs and options are
  unchanged.

>>> from core.runs import Stages
>>> Stages.__name__
'Stages'
"""

from core.lazy import lazy_exports

_EXPORTS = {
    **dict.fromkeys(["read_manifest", "check_output", "check_output_file", "output_dir",
                     "writing"], "outputs"),
    **dict.fromkeys(["Stages", "files_key"], "stages"),
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
