"""Calibration targets: ChArUco and chessboard boards with exact corner positions.

The target frame is OpenCV's board frame: origin at the board's top-left corner
(of the squares, excluding the white margin), x right, y down, z = 0 on the board,
the printed face looking toward -z. Both the renderer (to draw the board) and the
reconstruction (to detect it) use these classes, so the geometry lives once.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.validate import check_choice, check_int, check_positive

__all__ = ["ChArUcoTarget", "ChessboardTarget", "target_from_dict", "target_from_spec"]

_DICTS = ("DICT_4X4_50", "DICT_4X4_100", "DICT_5X5_100", "DICT_5X5_250", "DICT_6X6_250")


@dataclass
class _Board:
    margin_squares: float = 0.5

    def size_m(self) -> tuple[float, float]:
        """Printed size (width, height) of the squares area in metres."""
        return self.cols_squares * self.square_length, self.rows_squares * self.square_length

    def texture(self, px_per_square: int = 40) -> np.ndarray:
        """The printed board with its white margin, ``(h, w) uint8``."""
        img = self._squares_image(px_per_square)
        m = int(round(self.margin_squares * px_per_square))
        return np.pad(img, m, constant_values=255)

    def scene_object(self, name: str, world_from_target: np.ndarray, *, object_id: int = 0,
                     px_per_square: int = 40):
        """A thin textured plane (with margin) to place in a render scene."""
        from acquire.render.materials import Material
        from acquire.render.scene import SceneObject
        from core.meshes import make_mesh

        tex = self.texture(px_per_square)
        w, h = self.size_m()
        m = self.margin_squares * self.square_length
        x0, x1, y0, y1 = -m, w + m, -m, h + m
        v = np.array([[x0, y0, 0], [x1, y0, 0], [x1, y1, 0], [x0, y1, 0]], float)
        uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
        f = np.array([[0, 2, 1], [0, 3, 2]])  # normal -z: the printed face
        mesh = make_mesh(v, f, vertex_normals=np.tile([0, 0, -1.0], (4, 1)))
        mat = Material("image", image=np.repeat(tex[:, :, None], 3, axis=2))
        return SceneObject(name, mesh, mat, world_from_target, object_id, vertex_uvs=uv,
                           analytic={"type": "plane", "point": [0, 0, 0], "normal": [0, 0, -1]})


@dataclass
class ChArUcoTarget(_Board):
    """A ChArUco board.

    Parameters
    ----------
    squares_x, squares_y : int     squares along x and y
    square_length : float          metres
    marker_length : float          metres (< square_length)
    dictionary : str               an OpenCV ArUco dictionary name
    """

    squares_x: int = 7
    squares_y: int = 5
    square_length: float = 0.02
    marker_length: float = 0.015
    dictionary: str = "DICT_5X5_100"

    def __post_init__(self):
        self.squares_x = check_int(self.squares_x, "squares_x", 3)
        self.squares_y = check_int(self.squares_y, "squares_y", 3)
        self.square_length = check_positive(self.square_length, "square_length")
        self.marker_length = check_positive(self.marker_length, "marker_length")
        if self.marker_length >= self.square_length:
            raise ValueError("marker_length: expected less than square_length, "
                             f"got {self.marker_length} >= {self.square_length}")
        check_choice(self.dictionary, "dictionary", _DICTS)

    cols_squares = property(lambda self: self.squares_x)
    rows_squares = property(lambda self: self.squares_y)

    def cv_board(self):
        import cv2

        d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        return cv2.aruco.CharucoBoard((self.squares_x, self.squares_y), self.square_length,
                                      self.marker_length, d)

    def corner_points(self) -> np.ndarray:
        """Inner chessboard corners ``(k, 3) float64`` in the target frame (ids = rows)."""
        return np.asarray(self.cv_board().getChessboardCorners(), np.float64)

    def _squares_image(self, pps):
        return self.cv_board().generateImage((self.squares_x * pps, self.squares_y * pps),
                                             marginSize=0, borderBits=1)

    def detect(self, image: np.ndarray, *, min_corners: int = 6):
        """Detect ChArUco corners: ``(ids (k,) int, corners (k, 2) float64)`` or None."""
        import cv2

        gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)
        if gray.dtype != np.uint8:
            gray = (gray / 257).astype(np.uint8)
        det = cv2.aruco.CharucoDetector(self.cv_board())
        cc, ci, _, _ = det.detectBoard(gray)
        if ci is None or len(ci) < min_corners:
            return None
        return ci.ravel().astype(np.int64), cc.reshape(-1, 2).astype(np.float64)

    def to_dict(self) -> dict:
        return {"type": "charuco", "squares_x": self.squares_x, "squares_y": self.squares_y,
                "square_length": self.square_length, "marker_length": self.marker_length,
                "dictionary": self.dictionary, "margin_squares": self.margin_squares}


@dataclass
class ChessboardTarget(_Board):
    """A chessboard with ``cols x rows`` squares (inner corners (cols-1) x (rows-1))."""

    cols: int = 9
    rows: int = 6
    square_length: float = 0.02

    def __post_init__(self):
        self.cols = check_int(self.cols, "cols", 3)
        self.rows = check_int(self.rows, "rows", 3)
        self.square_length = check_positive(self.square_length, "square_length")
        self.margin_squares = max(self.margin_squares, 1.0)  # SB detector needs a white border

    cols_squares = property(lambda self: self.cols)
    rows_squares = property(lambda self: self.rows)

    def corner_points(self) -> np.ndarray:
        j, i = np.mgrid[1:self.rows, 1:self.cols]
        return np.stack([i.ravel() * self.square_length, j.ravel() * self.square_length,
                         np.zeros(i.size)], axis=1)

    def _squares_image(self, pps):
        j, i = np.mgrid[0:self.rows * pps, 0:self.cols * pps]
        return np.where(((i // pps) + (j // pps)) % 2 == 0, 0, 255).astype(np.uint8)

    def detect(self, image: np.ndarray, *, min_corners: int = 0):
        import cv2

        gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)
        ok, corners = cv2.findChessboardCornersSB(gray, (self.cols - 1, self.rows - 1),
                                                  flags=cv2.CALIB_CB_ACCURACY)
        if not ok:
            return None
        c = corners.reshape(-1, 2).astype(np.float64)
        # The detector's order is ambiguous up to a half turn. Our top-left square is
        # black: sample the centre of the outer square diagonal to corner 0 and
        # reverse the order if it is the lighter one of the two opposite corners.
        nx = self.cols - 1
        first = c[0] + 0.5 * (c[0] - c[1]) + 0.5 * (c[0] - c[nx])
        last = c[-1] + 0.5 * (c[-1] - c[-2]) + 0.5 * (c[-1] - c[-1 - nx])
        if _sample(gray, first) > _sample(gray, last):
            c = c[::-1].copy()
        return np.arange(len(c)), c

    def to_dict(self) -> dict:
        return {"type": "chessboard", "cols": self.cols, "rows": self.rows,
                "square_length": self.square_length, "margin_squares": self.margin_squares}


def _sample(gray: np.ndarray, p: np.ndarray) -> float:
    h, w = gray.shape
    x = int(np.clip(round(p[0]), 0, w - 1))
    y = int(np.clip(round(p[1]), 0, h - 1))
    return float(gray[max(y - 1, 0):y + 2, max(x - 1, 0):x + 2].mean())


def target_from_dict(d: dict):
    """Rebuild a target from its ``to_dict()`` form (as stored in capture.json)."""
    d = dict(d)
    kind = check_choice(d.pop("type", None), "target.type", ("charuco", "chessboard"))
    cls = ChArUcoTarget if kind == "charuco" else ChessboardTarget
    try:
        return cls(**d)
    except TypeError as exc:
        raise ValueError(f"target: {exc}") from None


TARGET_SPEC_HELP = ("chessboard:COLSxROWS:SQUARE (counted in squares, so OpenCV's 9x6 inner "
                    "corners are 10x7) or charuco:COLSxROWS:SQUARE:MARKER[:DICT]; lengths in "
                    "metres")


def target_from_spec(text: str):
    """A target from a one-line spec, as on the command line (:data:`TARGET_SPEC_HELP`):
    ``chessboard:10x7:0.025`` or ``charuco:7x5:0.02:0.015:DICT_5X5_100``."""
    parts = [p.strip() for p in str(text).split(":")]
    kind = parts[0].lower()
    want = {"chessboard": (3, 3), "charuco": (4, 5)}
    if kind not in want or not want[kind][0] <= len(parts) <= want[kind][1]:
        raise ValueError(f"board: expected {TARGET_SPEC_HELP}, got {text!r}")
    try:
        cols, rows = (int(v) for v in parts[1].lower().split("x"))
        lengths = [float(v) for v in parts[2:4] if v and not v.upper().startswith("DICT")]
    except ValueError:
        raise ValueError(f"board: expected {TARGET_SPEC_HELP}, got {text!r}") from None
    if kind == "chessboard":
        return ChessboardTarget(cols=cols, rows=rows, square_length=lengths[0])
    if len(lengths) != 2:
        raise ValueError(f"board: expected {TARGET_SPEC_HELP}, got {text!r}")
    extra = {"dictionary": parts[4]} if len(parts) == 5 else {}
    return ChArUcoTarget(squares_x=cols, squares_y=rows, square_length=lengths[0],
                         marker_length=lengths[1], **extra)
