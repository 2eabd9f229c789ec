"""core.config: options declared once, read from TOML, written back, overridden by name."""

from __future__ import annotations

from dataclasses import dataclass

import pytest

from core.config import (
    Config,
    from_dict,
    iter_options,
    load_config,
    option,
    to_dict,
    with_options,
    write_config,
)
from core.validate import InputError


@dataclass(frozen=True)
class Inner(Config):
    depth: int = option(9, help="octree depth", range="[4, 12]")
    size: tuple[float, float] = option((1.0, 2.0), unit="m", help="extent", range="(0, inf)")


@dataclass(frozen=True)
class Outer(Config):
    method: str = option("a", choices=("a", "b"), help="method")
    angle_deg: float = option(30.0, unit="deg", help="tilt", range="(0, 90)")
    name: str | None = option(None, help="optional name")
    on: bool = option(True, help="switch")
    inner: Inner = option(default_factory=lambda: Inner(depth=7), help="nested")


def test_round_trip_through_toml(tmp_path):
    cfg = Outer(method="b", angle_deg=45, name="x", inner=Inner(depth=10, size=(3, 4)))
    path = write_config(tmp_path / "config.toml", cfg)
    back = load_config(Outer, path)
    assert back == cfg
    assert isinstance(back.angle_deg, float) and back.inner.size == (3.0, 4.0)


def test_defaults_come_from_the_declaration():
    opts = {o.name: o for o in iter_options(Outer)}
    assert opts["inner.depth"].default == 7  # the parent's default_factory, not Inner's 9
    assert opts["angle_deg"].unit == "deg" and opts["angle_deg"].range == "(0, 90)"
    assert set(opts) == {"method", "angle_deg", "name", "on", "inner.depth", "inner.size"}


@pytest.mark.parametrize("table, field, words", [
    ({"angle_deg": 90}, "angle_deg", "(0, 90)"),
    ({"angle_deg": "x"}, "angle_deg", "a number"),
    ({"method": "c"}, "method", "'a', 'b'"),
    ({"on": 1}, "on", "true or false"),
    ({"inner": {"depth": 3}}, "inner.depth", "[4, 12]"),
    ({"inner": {"size": [1.0]}}, "inner.size", "2 values"),
    ({"inner": {"size": [1.0, -1.0]}}, "inner.size", "(0, inf)"),
    ({"inner": 5}, "inner", "expected Inner"),
    ({"bogus": 1}, "bogus", "unknown option"),
    ({"inner": {"bogus": 1}}, "inner.bogus", "unknown option"),
])
def test_errors_name_file_and_field(table, field, words):
    with pytest.raises(InputError) as exc:
        from_dict(Outer, table, path="run.toml")
    assert exc.value.path == "run.toml" and exc.value.field == field
    assert words in str(exc.value)


def test_dotted_overrides():
    cfg = with_options(Outer(), {"inner.depth": 11, "angle_deg": 10})
    assert cfg.inner.depth == 11 and cfg.angle_deg == 10.0 and cfg.inner.size == (1.0, 2.0)
    with pytest.raises(InputError, match="inner.depth"):
        with_options(Outer(), {"inner.depth": 13})
    with pytest.raises(InputError, match="not a table"):
        with_options(Outer(), {"on.x": 1})


def test_none_is_left_out_and_reads_back():
    assert "name" not in to_dict(Outer())
    assert from_dict(Outer, to_dict(Outer())) == Outer()
