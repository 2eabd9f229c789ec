"""LAS 1.4 and LAZ point files (laspy + lazrs): the one place that knows the format.

Surveys keep the coordinates they came in (projected CRS, millions of metres). A LAS
file stores integers ``X = round((x - offset) / scale)``: the writer chooses the offset
once (the survey's origin, rounded to the metre) and the scale (1 mm by default), so
every point of every chunk is exact to the scale. Points are passed and returned as a
dict of named numpy arrays, one per dimension (laspy's and PDAL's names):

========================  ==========  ==================================================
name                      dtype       meaning
========================  ==========  ==================================================
x, y, z                   float64     coordinates (metres, the file's CRS)
intensity                 uint16      return strength
return_number             uint8       1 .. 15
number_of_returns         uint8       1 .. 15
gps_time                  float64     seconds (adjusted standard GPS time, GPS - 1e9)
scan_angle                float32     degrees (stored in steps of 0.006 degree)
point_source_id           uint16      the strip (flight line) or station
classification            uint8       ASPRS class (:class:`AsprsClass`)
<extra>                   any         named extra dimensions ("extra bytes")
========================  ==========  ==================================================

Writing streams: :class:`LasWriter` takes chunks and never holds the survey. Reading:
:func:`read_las` (all points) or :func:`iter_las_chunks` (``n`` points at a time).
Every reader error is an :class:`core.validate.InputError` naming the file and field.

>>> import numpy as np, tempfile, pathlib
>>> path = pathlib.Path(tempfile.mkdtemp()) / "a.laz"
>>> pts = {"x": np.array([5e5 + 0.1234]), "y": np.array([6.1e6]), "z": np.array([200.0])}
>>> with LasWriter(path, origin=(5e5, 6.1e6, 0.0)) as w:
...     w.write(pts)
>>> back, info = read_las(path)
>>> float(back["x"][0]), info.point_count
(500000.123, 1)
"""

from __future__ import annotations

import contextlib
import datetime
import enum
import os
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from core.files import atomic_file
from core.validate import InputError

__all__ = ["LasWriter", "LasInfo", "read_las", "iter_las_chunks", "STANDARD_FIELDS",
           "SCAN_ANGLE_STEP_DEG", "gps_date", "AsprsClass", "ASPRS_NAMES"]


class AsprsClass(enum.IntEnum):
    """The ASPRS standard point classes (LAS 1.4 R15, table 17) that scanamp writes or
    reads: the one definition of their codes.

    >>> int(AsprsClass.GROUND), ASPRS_NAMES[AsprsClass.ROAD_SURFACE]
    (2, 'road surface')
    """

    UNCLASSIFIED = 1
    GROUND = 2
    LOW_VEGETATION = 3
    MEDIUM_VEGETATION = 4
    HIGH_VEGETATION = 5
    BUILDING = 6
    LOW_NOISE = 7
    WATER = 9
    ROAD_SURFACE = 11
    HIGH_NOISE = 18


#: The name of each class, by code.
ASPRS_NAMES = {int(c): c.name.lower().replace("_", " ") for c in AsprsClass}

#: The standard dimensions the writer fills (others of point format 6 stay zero).
STANDARD_FIELDS = ("x", "y", "z", "intensity", "return_number", "number_of_returns",
                   "gps_time", "scan_angle", "point_source_id", "classification")
#: LAS 1.4 point formats 6-10 store the scan angle as int16 in steps of 0.006 degree.
SCAN_ANGLE_STEP_DEG = 0.006
_INT_FIELDS = {"intensity": np.uint16, "return_number": np.uint8,
               "number_of_returns": np.uint8, "point_source_id": np.uint16,
               "classification": np.uint8}
_GPS_EPOCH = datetime.date(1980, 1, 6)


def gps_date(gps_time: float) -> datetime.date:
    """The calendar date of an adjusted standard GPS time (seconds, GPS time - 1e9).

    >>> gps_date(0.0)
    datetime.date(2011, 9, 14)
    """
    return _GPS_EPOCH + datetime.timedelta(seconds=float(gps_time) + 1e9)


@dataclass
class LasInfo:
    """What a LAS header says.

    Attributes
    ----------
    point_count : int
    version : str
        "1.2", "1.4", ...
    point_format : int
    scales, offsets : (3,) float64
    mins, maxs : (3,) float64
        Bounding box of the points (metres).
    crs_wkt : str or None
        The OGC WKT coordinate system when the file has one (LAS 1.4 WKT record, or the
        EPSG code of a LAS 1.2 GeoTIFF key directory).
    extra_dims : tuple of str
        Names of the extra dimensions (extra bytes).
    dims : tuple of str
        Every dimension :func:`read_las` returns.
    """

    point_count: int
    version: str
    point_format: int
    scales: np.ndarray
    offsets: np.ndarray
    mins: np.ndarray
    maxs: np.ndarray
    crs_wkt: str | None = None
    extra_dims: tuple = ()
    dims: tuple = field(default_factory=tuple)


class LasWriter:
    """Stream points to a LAS 1.4 / LAZ file (point format 6), chunk by chunk.

    The file appears at ``path`` only when the ``with`` block ends without an error
    (written to a temporary sibling first). ``.laz`` compresses (lazrs), ``.las`` not.

    Parameters
    ----------
    path : path ending in .las or .laz
    origin : (3,) float
        The survey's origin: the offset is this, rounded to the metre (kept for every chunk).
    scale : float
        Coordinate resolution, metres (1 mm).
    extra : mapping name -> numpy dtype
        Extra dimensions (extra bytes) the chunks carry, e.g. ``{"object_id": "int32"}``.
    crs_wkt : str, optional
        OGC WKT of the coordinate system (written as the LAS 1.4 WKT record).
    creation_date : datetime.date, optional
        The header's date (default: the GPS date of the first chunk's first point, so
        that the same survey gives the same bytes).
    system_identifier, generating_software : str
    """

    def __init__(self, path: str | os.PathLike, *, origin=(0.0, 0.0, 0.0), scale: float = 0.001,
                 extra: Mapping[str, object] | None = None, crs_wkt: str | None = None,
                 creation_date: datetime.date | None = None,
                 system_identifier: str = "scanamp simulation",
                 generating_software: str = "scanamp"):
        self.path = Path(path)
        if self.path.suffix.lower() not in (".las", ".laz"):
            raise InputError(f"expected a .las or .laz file, got {self.path.suffix!r}",
                             path=self.path)
        origin = np.asarray(origin, np.float64)
        if origin.shape != (3,) or not np.all(np.isfinite(origin)):
            raise InputError(f"expected 3 finite numbers, got {origin!r}", field="origin")
        if not (np.isfinite(scale) and scale > 0):
            raise InputError(f"expected a positive scale, got {scale!r}", field="scale")
        self.offsets = np.round(origin)
        self.scale = float(scale)
        self.extra = {str(k): np.dtype(v) for k, v in (extra or {}).items()}
        clash = set(self.extra) & set(STANDARD_FIELDS)
        if clash:
            raise InputError(f"extra dimensions clash with standard ones: {sorted(clash)}",
                             field="extra")
        self.crs_wkt = crs_wkt
        self.creation_date = creation_date
        self.system_identifier = system_identifier
        self.generating_software = generating_software
        self.point_count = 0
        self._atomic = None
        self._tmp = None
        self._writer = None
        self._header = None

    def _make_header(self, date: datetime.date):
        import laspy

        h = laspy.LasHeader(point_format=6, version="1.4")
        h.offsets = self.offsets
        h.scales = np.full(3, self.scale)
        h.global_encoding.gps_time_type = laspy.header.GpsTimeType.STANDARD
        h.creation_date = date
        h.system_identifier = self.system_identifier[:32]
        h.generating_software = self.generating_software[:32]
        for name, dt in self.extra.items():
            h.add_extra_dim(laspy.ExtraBytesParams(name=name, type=dt))
        if self.crs_wkt:
            from laspy.vlrs.known import WktCoordinateSystemVlr

            h.vlrs.append(WktCoordinateSystemVlr(self.crs_wkt))
            h.global_encoding.wkt = True
        return h

    def __enter__(self) -> LasWriter:
        self._atomic = atomic_file(self.path)
        self._tmp = self._atomic.__enter__()
        return self

    def _open(self, first_gps: float) -> None:
        import laspy

        date = self.creation_date or gps_date(first_gps)
        self._header = self._make_header(date)
        self._writer = laspy.open(self._tmp, mode="w", header=self._header,
                                  do_compress=self.path.suffix.lower() == ".laz")

    def write(self, points: Mapping[str, np.ndarray]) -> None:
        """Append a chunk: a dict of equal-length arrays (``x``, ``y``, ``z`` required;
        other standard fields default to 0, return numbers to 1; every extra dimension
        declared at construction is required)."""
        import laspy

        if self._tmp is None:
            raise RuntimeError("LasWriter.write outside its 'with' block")
        n = len(np.asarray(points["x"]))
        for k, v in points.items():
            if len(np.asarray(v)) != n:
                raise InputError(f"expected {n} values like x, got {len(np.asarray(v))}", field=k)
        unknown = set(points) - set(STANDARD_FIELDS) - set(self.extra)
        if unknown:
            raise InputError(f"not a standard dimension nor a declared extra one: "
                             f"{sorted(unknown)}", field="points")
        if self._writer is None:
            gps = np.asarray(points.get("gps_time", [0.0]), np.float64)
            self._open(float(gps[0]) if len(gps) else 0.0)
        if n == 0:
            return
        rec = laspy.ScaleAwarePointRecord.zeros(n, header=self._header)
        for axis, name in enumerate(("x", "y", "z")):
            v = np.asarray(points[name], np.float64)
            if not np.all(np.isfinite(v)):
                raise InputError("expected finite coordinates", field=name)
            q = np.round((v - self.offsets[axis]) / self.scale)
            if np.abs(q).max() >= 2**31:
                raise InputError(f"coordinates beyond the int32 range of scale {self.scale} "
                                 f"about offset {self.offsets[axis]}", field=name)
            rec[name.upper()] = q.astype(np.int32)
        for name in ("return_number", "number_of_returns"):
            v = np.asarray(points.get(name, np.ones(n)))
            if v.min() < 1 or v.max() > 15:
                raise InputError("expected values in 1 .. 15", field=name)
            rec[name] = v.astype(np.uint8)
        for name in ("intensity", "point_source_id", "classification"):
            if name in points:
                rec[name] = np.asarray(points[name]).astype(_INT_FIELDS[name])
        if "gps_time" in points:
            rec["gps_time"] = np.asarray(points["gps_time"], np.float64)
        if "scan_angle" in points:
            ang = np.round(np.asarray(points["scan_angle"], np.float64) / SCAN_ANGLE_STEP_DEG)
            rec["scan_angle"] = np.clip(ang, -30000, 30000).astype(np.int16)
        for name, dt in self.extra.items():
            if name not in points:
                raise InputError("the chunk lacks this declared extra dimension", field=name)
            rec[name] = np.asarray(points[name]).astype(dt)
        self._writer.write_points(rec)
        self.point_count += n

    def __exit__(self, exc_type, exc, tb):
        try:
            if exc_type is None and self._writer is None:
                self._open(0.0)            # an empty survey is still a valid file
            if self._writer is not None:
                self._writer.close()
        except BaseException as e:
            self._atomic.__exit__(type(e), e, e.__traceback__)
            raise
        return self._atomic.__exit__(exc_type, exc, tb)


def _open_reader(path: Path):
    import laspy

    if not path.is_file():
        raise InputError("file not found", path=path)
    if path.suffix.lower() not in (".las", ".laz"):
        raise InputError(f"expected a .las or .laz file, got {path.suffix!r}", path=path)
    try:
        return laspy.open(path, mode="r")
    except Exception as e:  # laspy raises its own errors for a bad header
        raise InputError(f"not a readable LAS/LAZ file ({e})", path=path, field="header") from None


def _geokeys_wkt(vlr) -> str | None:
    """WKT of the EPSG code in a LAS 1.2 GeoTIFF key directory (projected 3072, else
    geographic 2048), through rasterio; None when there is none or it is unknown."""
    codes = {k.id: k.value_offset for k in getattr(vlr, "geo_keys", [])
             if k.tiff_tag_location == 0}
    code = codes.get(3072) or codes.get(2048)
    if not code or code == 32767:        # 32767: user-defined, not an EPSG code
        return None
    try:
        from rasterio.crs import CRS

        return CRS.from_epsg(int(code)).to_wkt()
    except Exception:  # rasterio missing or an unknown code: no CRS rather than no file
        return None


def _info(path: Path, header) -> LasInfo:
    wkt = None
    for vlr in list(header.vlrs) + list(getattr(header, "evlrs", None) or []):
        if getattr(vlr, "record_id", None) == 2112 and hasattr(vlr, "string"):
            wkt = vlr.string.rstrip("\0") or None
        elif getattr(vlr, "record_id", None) == 34735 and wkt is None:
            wkt = _geokeys_wkt(vlr)
    extra = tuple(header.point_format.extra_dimension_names)
    names = set(header.point_format.dimension_names)
    if "scan_angle_rank" in names:
        names.add("scan_angle")
    std = [d for d in STANDARD_FIELDS if d in {"x", "y", "z"} or d in names]
    return LasInfo(point_count=int(header.point_count), version=str(header.version),
                   point_format=int(header.point_format.id),
                   scales=np.asarray(header.scales, np.float64),
                   offsets=np.asarray(header.offsets, np.float64),
                   mins=np.asarray(header.mins, np.float64),
                   maxs=np.asarray(header.maxs, np.float64),
                   crs_wkt=wkt, extra_dims=extra, dims=tuple(std) + extra)


def _as_dict(rec, info: LasInfo, fields) -> dict:
    out = {}
    for name in fields:
        if name in ("x", "y", "z"):
            out[name] = np.asarray(getattr(rec, name), np.float64)
        elif name == "scan_angle":
            raw = np.asarray(rec["scan_angle"] if info.point_format >= 6
                             else rec["scan_angle_rank"], np.float64)
            out[name] = (raw * (SCAN_ANGLE_STEP_DEG if info.point_format >= 6 else 1.0)
                         ).astype(np.float32)
        elif name in _INT_FIELDS:
            out[name] = np.asarray(rec[name]).astype(_INT_FIELDS[name])
        else:
            out[name] = np.array(rec[name])
    return out


def _fields(info: LasInfo, fields, path: Path) -> tuple:
    if fields is None:
        return info.dims
    names = tuple(fields)
    for name in names:
        if name not in info.dims:
            raise InputError(f"no such dimension; the file has {list(info.dims)}",
                             path=path, field=name)
    return names


@contextlib.contextmanager
def _points_reader(path: Path, fields):
    """``(reader, info, names)`` of an open LAS/LAZ file that has points; ``fields``
    checked against its dimensions."""
    with _open_reader(path) as reader:
        info = _info(path, reader.header)
        names = _fields(info, fields, path)
        if info.point_count == 0:
            raise InputError("the file has no points", path=path, field="points")
        yield reader, info, names


def read_las(path: str | os.PathLike, *, fields=None) -> tuple[dict, LasInfo]:
    """All points of a LAS/LAZ file: ``(dict name -> (n,) array, LasInfo)``.

    ``fields`` restricts the dimensions returned (default: every standard one the point
    format has, and every extra dimension). A file without points raises InputError.
    """
    path = Path(path)
    with _points_reader(path, fields) as (reader, info, names):
        try:
            rec = reader.read_points(info.point_count)
        except Exception as e:
            raise InputError(f"truncated or corrupt point data ({e})", path=path,
                             field="points") from None
        if len(rec) != info.point_count:
            raise InputError(f"the header says {info.point_count} points, the file holds "
                             f"{len(rec)}", path=path, field="points")
        return _as_dict(rec, info, names), info


def iter_las_chunks(path: str | os.PathLike, n: int = 1_000_000, *,
                    fields=None) -> Iterator[tuple[dict, LasInfo]]:
    """Yield ``(dict name -> array, LasInfo)`` for successive chunks of at most ``n`` points."""
    path = Path(path)
    if int(n) < 1:
        raise InputError(f"expected a chunk size >= 1, got {n}", field="n")
    with _points_reader(path, fields) as (reader, info, names):
        try:
            for rec in reader.chunk_iterator(int(n)):
                yield _as_dict(rec, info, names), info
        except InputError:
            raise
        except Exception as e:
            raise InputError(f"truncated or corrupt point data ({e})", path=path,
                             field="points") from None
