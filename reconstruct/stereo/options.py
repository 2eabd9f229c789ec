"""The stereo pipelines' options (``scanamp reconstruct stereo``), shared by the capture
pipeline (:mod:`reconstruct.stereo.pipeline`) and the pair pipeline
(:mod:`reconstruct.stereo.pair`)."""

from __future__ import annotations

from dataclasses import dataclass

from core.config import Config, option
from reconstruct.stereo.matching import MatchOptions

__all__ = ["StereoOptions"]


@dataclass
class StereoOptions(Config):
    """Options of the stereo pipelines (``scanamp reconstruct stereo``); the matcher's are
    :class:`reconstruct.stereo.matching.MatchOptions`'s."""

    mode: str = option("auto", choices=("auto", "passive", "active"),
                       help="which images to match ('auto': the dot-pattern images when "
                            "present)")
    compare: bool = option(True, help="with a capture holding both, also reconstruct and "
                                      "score the other mode")
    block_size: int = option(5, unit="px", range="[1, 31]", help="SGBM window (odd)")
    wls: bool = option(False, help="WLS disparity filter (ximgproc)")
    lr_check: bool = option(False, help="left-right consistency check")
    lr_tol: float = option(1.0, unit="px", range="(0, inf)",
                           help="left-right disagreement tolerated by the check")
    uniqueness: int = option(5, unit="%", range="[0, 100]", help="SGBM uniqueness ratio")
    sgbm_mode: str = option("sgbm", choices=("sgbm", "hh", "3way"), help="OpenCV SGBM mode")
    voxel_size: float | None = option(None, unit="m", range="(0, inf)",
                                      help="TSDF voxel (default: far working distance / 500)")
    min_disparity: int | None = option(None, unit="px",
                                       help="search range start (default from the rig's "
                                            "working range)")
    num_disparities: int | None = option(None, unit="px", range="[16, 4096]",
                                         help="search range, a multiple of 16 (default from "
                                              "the rig's working range)")

    def match_options(self, lo: int, num: int) -> MatchOptions:
        return MatchOptions(min_disparity=lo, num_disparities=num, block_size=self.block_size,
                            wls=self.wls, lr_check=self.lr_check, lr_tol=self.lr_tol,
                            uniqueness=self.uniqueness, mode=self.sgbm_mode)
