"""What a reconstruction pipeline returns: its output folder and its report, in memory.

Every pipeline (``reconstruct.<method>.pipeline``) writes ``report.json`` into its folder
(the public record of the run) and returns the same report in a
:class:`ReconstructionResult`, so a caller never reads the file it was just handed.
The result also names its folder: ``Path(result)`` and ``result / "mesh.ply"`` work as
with the folder itself.

>>> from pathlib import Path
>>> res = ReconstructionResult(Path("out"), {"points": 3})
>>> res / "mesh.ply", res.report["points"], res.ok
(PosixPath('out/mesh.ply'), 3, True)
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

__all__ = ["ReconstructionResult"]


@dataclass(frozen=True)
class ReconstructionResult:
    """A reconstruction's folder and its ``report.json`` (as plain JSON data).

    ``ok`` False: the algorithm failed but still wrote a report (SfM registering too few
    images); ``message`` says why.
    """

    out_dir: Path
    report: dict
    ok: bool = True
    message: str = ""

    def __post_init__(self):
        object.__setattr__(self, "out_dir", Path(self.out_dir))

    def __fspath__(self) -> str:
        return os.fspath(self.out_dir)

    def __truediv__(self, name: str | os.PathLike) -> Path:
        return self.out_dir / name

    def __str__(self) -> str:
        return str(self.out_dir)
