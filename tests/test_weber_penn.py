"""Weber & Penn trees (procgen/weber_penn, core/qsm_io, scanamp procgen tree): the published
parameter sets transcribed exactly, parameter files checked, the QSM a tree that round trips,
the laws of real trees on small trees, same seed same bytes, the CLI's bad inputs."""

from __future__ import annotations

import re

import numpy as np
import pytest

from core.io.qsm import QSM, check_qsm, read_qsm_csv, write_qsm_csv
from core.validate import InputError
from procgen.weber_penn import (
    grow,
    laws,
    load_species,
    params_to_dict,
    parse_params,
    species_names,
    tree_mesh,
    tree_qsm,
    write_species,
)
from procgen.weber_penn.shapes import shape_ratio, taper_radius

# The published parameter sets as the reference tables give them (Weber & Penn 1995, in
# Arbaro's files); every value given there must come back from the shipped TOML file.
PUBLISHED = {
    "quaking_aspen": {
        "Shape": 7.0, "Levels": 3.0, "Scale": 13.0, "ScaleV": 3.0, "BaseSize": 0.4,
        "Ratio": 0.015, "RatioPower": 1.2, "Flare": 0.6, "Lobes": 5.0, "LobeDepth": 0.07,
        "Smooth": 0.5, "Leaves": 25.0, "LeafShape": 0.0, "LeafScale": 0.17, "LeafScaleX": 1.0,
        "LeafQuality": 1.0, "LeafStemLen": 0.5, "LeafDistrib": 4.0, "LeafBend": 0.3,
        "AttractionUp": 0.5, "PruneRatio": 0.0, "PrunePowerLow": 0.5, "PrunePowerHigh": 0.5,
        "PruneWidth": 0.5, "PruneWidthPeak": 0.5, "0Scale": 1.0, "0ScaleV": 0.2,
        "0BaseSplits": 0.0, "0DownAngle": 0.0, "0DownAngleV": 0.0, "0Rotate": 0.0,
        "0RotateV": 0.0, "0Branches": 1.0, "0BranchDist": 0.0, "0Length": 1.0, "0LengthV": 0.0,
        "0Taper": 1.0, "0SegSplits": 0.0, "0SplitAngle": 0.0, "0SplitAngleV": 0.0,
        "0CurveRes": 3.0, "0Curve": 0.0, "0CurveBack": 0.0, "0CurveV": 20.0,
        "1DownAngle": 60.0, "1DownAngleV": -50.0, "1Rotate": 140.0, "1RotateV": 0.0,
        "1Branches": 50.0, "1BranchDist": 1.0, "1Length": 0.3, "1LengthV": 0.0, "1Taper": 1.0,
        "1SegSplits": 0.0, "1SplitAngle": 0.0, "1SplitAngleV": 0.0, "1CurveRes": 5.0,
        "1Curve": -40.0, "1CurveBack": 0.0, "1CurveV": 50.0, "2DownAngle": 45.0,
        "2DownAngleV": 10.0, "2Rotate": 140.0, "2RotateV": 0.0, "2Branches": 30.0,
        "2BranchDist": 1.0, "2Length": 0.6, "2LengthV": 0.0, "2Taper": 1.0, "2SegSplits": 0.0,
        "2SplitAngle": 0.0, "2SplitAngleV": 0.0, "2CurveRes": 3.0, "2Curve": -40.0,
        "2CurveBack": 0.0, "2CurveV": 75.0, "3DownAngle": 45.0, "3DownAngleV": 10.0,
        "3Rotate": 77.0, "3RotateV": 0.0,
    },
    "black_tupelo": {
        "Shape": 4.0, "BaseSize": 0.2, "Scale": 23.0, "ScaleV": 5.0, "Levels": 4.0,
        "Ratio": 0.015, "RatioPower": 1.3, "Lobes": 3.0, "LobeDepth": 0.1, "Flare": 1.0,
        "Leaves": 6.0, "LeafShape": 0.0, "LeafScale": 0.3, "LeafScaleX": 0.5,
        "AttractionUp": 0.5, "0Scale": 1.0, "0ScaleV": 0.0, "0BaseSplits": 0.0, "0Length": 1.0,
        "0LengthV": 0.0, "0Taper": 1.1, "0SegSplits": 0.0, "0SplitAngle": 0.0,
        "0SplitAngleV": 0.0, "0CurveRes": 10.0, "0Curve": 0.0, "0CurveV": 40.0,
        "0CurveBack": 0.0, "1DownAngle": 60.0, "1DownAngleV": -40.0, "1Rotate": 140.0,
        "1RotateV": 0.0, "1Branches": 50.0, "1Length": 0.3, "1LengthV": 0.05, "1Taper": 1.0,
        "1SegSplits": 0.0, "1SplitAngle": 0.0, "1SplitAngleV": 0.0, "1CurveRes": 10.0,
        "1Curve": 0.0, "1CurveV": 90.0, "1CurveBack": 0.0, "2DownAngle": 30.0,
        "2DownAngleV": 10.0, "2Rotate": 140.0, "2RotateV": 0.0, "2Branches": 25.0,
        "2Length": 0.6, "2LengthV": 0.1, "2Taper": 1.0, "2SegSplits": 0.0, "2SplitAngle": 0.0,
        "2SplitAngleV": 0.0, "2CurveRes": 10.0, "2Curve": -10.0, "2CurveV": 150.0,
        "2CurveBack": 0.0, "3DownAngle": 45.0, "3DownAngleV": 10.0, "3Rotate": 140.0,
        "3RotateV": 0.0, "3Branches": 12.0, "3Length": 0.4, "3LengthV": 0.0, "3Taper": 1.0,
        "3SegSplits": 0.0, "3SplitAngle": 0.0, "3SplitAngleV": 0.0, "3CurveRes": 1.0,
        "3Curve": 0.0, "3CurveV": 0.0, "3CurveBack": 0.0,
    },
    "ca_black_oak": {
        "Shape": 2.0, "BaseSize": 0.05, "Scale": 10.0, "ScaleV": 10.0, "Levels": 3.0,
        "Ratio": 0.018, "RatioPower": 1.3, "Lobes": 5.0, "LobeDepth": 0.1, "Flare": 1.2,
        "Leaves": 25.0, "LeafShape": 0.0, "LeafScale": 0.12, "LeafScaleX": 0.66,
        "AttractionUp": 0.8, "0Scale": 1.0, "0ScaleV": 0.0, "0BaseSplits": 2.0, "0Length": 1.0,
        "0LengthV": 0.0, "0Taper": 0.95, "0SegSplits": 0.4, "0SplitAngle": 10.0,
        "0SplitAngleV": 0.0, "0CurveRes": 8.0, "0Curve": 0.0, "0CurveV": 90.0,
        "0CurveBack": 0.0, "1DownAngle": 30.0, "1DownAngleV": -30.0, "1Rotate": 80.0,
        "1RotateV": 0.0, "1Branches": 40.0, "1Length": 0.8, "1LengthV": 0.1, "1Taper": 1.0,
        "1SegSplits": 0.2, "1SplitAngle": 10.0, "1SplitAngleV": 10.0, "1CurveRes": 10.0,
        "1Curve": 40.0, "1CurveV": 150.0, "1CurveBack": -70.0, "2DownAngle": 45.0,
        "2DownAngleV": 10.0, "2Rotate": 140.0, "2RotateV": 0.0, "2Branches": 120.0,
        "2Length": 0.2, "2LengthV": 0.05, "2Taper": 0.05, "2SegSplits": 0.1,
        "2SplitAngle": 10.0, "2SplitAngleV": 10.0, "2CurveRes": 3.0, "2Curve": -40.0,
        "2CurveV": 30.0, "2CurveBack": 0.0, "3DownAngle": 45.0, "3DownAngleV": 10.0,
        "3Rotate": 140.0, "3RotateV": 0.0, "3Branches": 0.0, "3Length": 0.4, "3LengthV": 0.0,
        "3Taper": 1.0, "3SegSplits": 0.0, "3SplitAngle": 0.0, "3SplitAngleV": 0.0,
        "3CurveRes": 1.0, "3Curve": 0.0, "3CurveV": 0.0, "3CurveBack": 0.0,
    },
    "weeping_willow": {
        "Shape": 3.0, "Levels": 4.0, "Scale": 15.0, "ScaleV": 5.0, "BaseSize": 0.05,
        "Ratio": 0.03, "RatioPower": 2.0, "Flare": 0.75, "Lobes": 9.0, "LobeDepth": 0.03,
        "Smooth": 0.5, "Leaves": 10.0, "LeafShape": 'disc2', "LeafScale": 0.12,
        "LeafScaleX": 0.2, "LeafQuality": 1.0, "LeafStemLen": 0.5, "LeafDistrib": 3.0,
        "LeafBend": 0.3, "AttractionUp": -2.0, "PruneRatio": 1.0, "PrunePowerLow": 0.001,
        "PrunePowerHigh": 0.5, "PruneWidth": 0.4, "PruneWidthPeak": 0.6, "0Scale": 1.0,
        "0ScaleV": 0.0, "0BaseSplits": 2.0, "0DownAngle": 0.0, "0DownAngleV": 0.0,
        "0Rotate": 0.0, "0RotateV": 0.0, "0Branches": 1.0, "0BranchDist": 0.0, "0Length": 0.8,
        "0LengthV": 0.0, "0Taper": 1.0, "0SegSplits": 0.1, "0SplitAngle": 3.0,
        "0SplitAngleV": 0.0, "0CurveRes": 8.0, "0Curve": 0.0, "0CurveBack": 20.0,
        "0CurveV": 120.0, "1DownAngle": 20.0, "1DownAngleV": 10.0, "1Rotate": -120.0,
        "1RotateV": 30.0, "1Branches": 25.0, "1BranchDist": 1.0, "1Length": 0.5,
        "1LengthV": 0.1, "1Taper": 1.0, "1SegSplits": 0.2, "1SplitAngle": 30.0,
        "1SplitAngleV": 10.0, "1CurveRes": 16.0, "1Curve": 40.0, "1CurveBack": 80.0,
        "1CurveV": 90.0, "2DownAngle": 30.0, "2DownAngleV": 10.0, "2Rotate": -120.0,
        "2RotateV": 30.0, "2Branches": 10.0, "2BranchDist": 1.0, "2Length": 1.5,
        "2LengthV": 0.0, "2Taper": 1.0, "2SegSplits": 0.2, "2SplitAngle": 45.0,
        "2SplitAngleV": 20.0, "2CurveRes": 12.0, "2Curve": 0.0, "2CurveBack": 0.0,
        "2CurveV": 0.0, "3DownAngle": 20.0, "3DownAngleV": 10.0, "3Rotate": 140.0,
        "3RotateV": 0.0, "3Branches": 150.0, "3BranchDist": 1.0, "3Length": 0.1,
        "3LengthV": 0.0, "3Taper": 1.0, "3SegSplits": 0.0, "3SplitAngle": 0.0,
        "3SplitAngleV": 0.0, "3CurveRes": 1.0, "3Curve": 0.0, "3CurveBack": 0.0,
        "3CurveV": 0.0,
    },
    "sassafras": {
        "Shape": 2.0, "Levels": 4.0, "Scale": 23.0, "ScaleV": 7.0, "BaseSize": 0.2,
        "Ratio": 0.02, "RatioPower": 1.3, "Lobes": 3.0, "LobeDepth": 0.05, "Flare": 0.5,
        "Leaves": 15.0, "LeafShape": 0.0, "LeafScale": 0.25, "LeafScaleX": 0.7,
        "AttractionUp": 0.5, "PruneRatio": 0.0, "0Scale": 1.0, "0ScaleV": 0.0, "0Length": 1.0,
        "0LengthV": 0.0, "0Taper": 1.05, "0BaseSplits": 0.0, "0SegSplits": 0.0,
        "0SplitAngle": 20.0, "0SplitAngleV": 5.0, "0CurveRes": 16.0, "0CurveBack": 0.0,
        "0Curve": 0.0, "0CurveV": 60.0, "1Length": 0.4, "1LengthV": 0.0, "1Taper": 1.0,
        "1DownAngle": 90.0, "1DownAngleV": -10.0, "1Rotate": 140.0, "1RotateV": 0.0,
        "1Branches": 15.0, "1SegSplits": 0.0, "1CurveRes": 15.0, "1CurveBack": 30.0,
        "1Curve": -60.0, "1CurveV": 200.0, "2Length": 0.7, "2LengthV": 0.0, "2Taper": 1.0,
        "2DownAngle": 50.0, "2DownAngleV": 10.0, "2Rotate": 140.0, "2RotateV": 0.0,
        "2Branches": 20.0, "2SegSplits": 0.0, "2CurveRes": 8.0, "2CurveBack": 0.0,
        "2Curve": -40.0, "2CurveV": 300.0, "3Length": 0.4, "3LengthV": 0.0, "3Taper": 1.0,
        "3DownAngle": 45.0, "3DownAngleV": 10.0, "3Rotate": 140.0, "3RotateV": 0.0,
        "3Branches": 30.0, "3SplitAngle": 0.0, "3SplitAngleV": 0.0, "3SegSplits": 0.0,
        "3CurveRes": 3.0, "3CurveBack": 0.0, "3Curve": 0.0, "3CurveV": 200.0,
    },
    "european_larch": {
        "Shape": 0.0, "Levels": 3.0, "Scale": 15.0, "ScaleV": 7.0, "BaseSize": 0.25,
        "Ratio": 0.015, "RatioPower": 1.3, "Flare": 0.3, "Lobes": 0.0, "LobeDepth": 0.05,
        "Smooth": 0.5, "Leaves": 100.0, "LeafShape": 'disc1', "LeafScale": 0.03,
        "LeafScaleX": 0.2, "LeafQuality": 0.5, "LeafStemLen": 0.0, "LeafDistrib": 3.0,
        "LeafBend": 0.3, "AttractionUp": -2.0, "PruneRatio": 0.0, "PrunePowerLow": 0.5,
        "PrunePowerHigh": 0.5, "PruneWidth": 0.5, "PruneWidthPeak": 0.5, "0Scale": 1.0,
        "0ScaleV": 0.0, "0BaseSplits": 0.0, "0DownAngle": 0.0, "0DownAngleV": 0.0,
        "0Rotate": 0.0, "0RotateV": 0.0, "0Branches": 1.0, "0BranchDist": 0.0, "0Length": 1.0,
        "0LengthV": 0.0, "0Taper": 1.0, "0SegSplits": 0.0, "0SplitAngle": 0.0,
        "0SplitAngleV": 0.0, "0CurveRes": 20.0, "0Curve": 0.0, "0CurveBack": 0.0,
        "0CurveV": 20.0, "1DownAngle": 60.0, "1DownAngleV": -50.0, "1Rotate": 70.0,
        "1RotateV": 30.0, "1Branches": 60.0, "1BranchDist": 0.5, "1Length": 0.25,
        "1LengthV": 0.15, "1Taper": 1.0, "1SegSplits": 0.0, "1SplitAngle": 0.0,
        "1SplitAngleV": 0.0, "1CurveRes": 17.0, "1Curve": 20.0, "1CurveBack": -100.0,
        "1CurveV": 120.0, "2DownAngle": 70.0, "2DownAngleV": 30.0, "2Rotate": 70.0,
        "2RotateV": 30.0, "2Branches": 50.0, "2BranchDist": 1.0, "2Length": 0.3,
        "2LengthV": 0.1, "2Taper": 1.0, "2SegSplits": 0.15, "2SplitAngle": 40.0,
        "2SplitAngleV": 10.0, "2CurveRes": 7.0, "2Curve": 0.0, "2CurveBack": 0.0,
        "2CurveV": 0.0, "3DownAngle": 30.0, "3DownAngleV": 0.0, "3Rotate": 120.0,
        "3RotateV": 0.0,
    },
    "lombardy_poplar": {
        "Shape": 2.0, "Levels": 3.0, "Scale": 25.0, "ScaleV": 5.0, "BaseSize": 0.0,
        "Ratio": 0.015, "RatioPower": 1.3, "Flare": 0.8, "Lobes": 7.0, "LobeDepth": 0.05,
        "Smooth": 0.5, "Leaves": 12.0, "LeafShape": 0.0, "LeafScale": 0.2, "LeafScaleX": 1.0,
        "LeafQuality": 1.0, "LeafStemLen": 0.5, "LeafDistrib": 4.0, "LeafBend": 0.5,
        "AttractionUp": 0.5, "PruneRatio": 0.0, "PrunePowerLow": 0.5, "PrunePowerHigh": 0.5,
        "PruneWidth": 0.5, "PruneWidthPeak": 0.5, "0Scale": 0.8, "0ScaleV": 0.0,
        "0BaseSplits": 0.0, "0DownAngle": 0.0, "0DownAngleV": 0.0, "0Rotate": 0.0,
        "0RotateV": 0.0, "0Branches": 1.0, "0BranchDist": 0.0, "0Length": 1.0, "0LengthV": 0.0,
        "0Taper": 1.0, "0SegSplits": 0.0, "0SplitAngle": 0.0, "0SplitAngleV": 0.0,
        "0CurveRes": 1.0, "0Curve": 0.0, "0CurveBack": 0.0, "0CurveV": 15.0,
        "1DownAngle": 30.0, "1DownAngleV": 0.0, "1Rotate": 77.0, "1RotateV": 0.0,
        "1Branches": 40.0, "1BranchDist": 1.0, "1Length": 0.3, "1LengthV": 0.0, "1Taper": 1.0,
        "1SegSplits": 0.0, "1SplitAngle": 0.0, "1SplitAngleV": 0.0, "1CurveRes": 3.0,
        "1Curve": -20.0, "1CurveBack": 0.0, "1CurveV": 0.0, "2DownAngle": 30.0,
        "2DownAngleV": 10.0, "2Rotate": 77.0, "2RotateV": 0.0, "2Branches": 30.0,
        "2BranchDist": 1.0, "2Length": 0.4, "2LengthV": 0.0, "2Taper": 1.0, "2SegSplits": 0.0,
        "2SplitAngle": 0.0, "2SplitAngleV": 0.0, "2CurveRes": 3.0, "2Curve": -20.0,
        "2CurveBack": 0.0, "2CurveV": 40.0, "3DownAngle": 30.0, "3DownAngleV": 10.0,
        "3Rotate": 77.0, "3RotateV": 0.0,
    },
    "palm": {
        "Shape": 4.0, "Levels": 2.0, "Scale": 12.0, "ScaleV": 10.0, "BaseSize": 0.95,
        "Ratio": 0.015, "RatioPower": 2.0, "Flare": 0.0, "Lobes": 0.0, "LobeDepth": 0.0,
        "Smooth": 0.5, "Leaves": 250.0, "LeafShape": 'palm', "LeafScale": 0.6,
        "LeafScaleX": 0.06, "LeafQuality": 1.0, "LeafStemLen": 0.0, "LeafDistrib": 4.0,
        "LeafBend": 0.3, "AttractionUp": 0.0, "PruneRatio": 0.0, "PrunePowerLow": 0.5,
        "PrunePowerHigh": 0.5, "PruneWidth": 0.5, "PruneWidthPeak": 0.5, "0Scale": 1.0,
        "0ScaleV": 0.0, "0BaseSplits": 0.0, "0DownAngle": 0.0, "0DownAngleV": 0.0,
        "0Rotate": 0.0, "0RotateV": 0.0, "0Branches": 1.0, "0BranchDist": 0.0, "0Length": 1.0,
        "0LengthV": 0.0, "0Taper": 2.1, "0SegSplits": 0.0, "0SplitAngle": 0.0,
        "0SplitAngleV": 0.0, "0CurveRes": 12.0, "0Curve": 20.0, "0CurveBack": -5.0,
        "0CurveV": 10.0, "1DownAngle": 70.0, "1DownAngleV": -80.0, "1Rotate": 120.0,
        "1RotateV": 60.0, "1Branches": 33.0, "1BranchDist": 1.0, "1Length": 0.4,
        "1LengthV": 0.05, "1Taper": 1.0, "1SegSplits": 0.0, "1SplitAngle": 0.0,
        "1SplitAngleV": 0.0, "1CurveRes": 9.0, "1Curve": 50.0, "1CurveBack": 0.0,
        "1CurveV": 20.0, "2DownAngle": 50.0, "2DownAngleV": -50.0, "2Rotate": -120.0,
        "2RotateV": 20.0,
    },
}


def _value(params, key):
    m = re.match(r"^([0-3])(\D.*)$", key)
    if m and m.group(2) not in ("Scale", "ScaleV", "BaseSplits"):
        return params.levels[int(m.group(1))][m.group(2)]
    return params.tree[key]


@pytest.mark.parametrize("name", sorted(PUBLISHED))
def test_each_published_species_reproduces_its_parameters_exactly(name):
    params = load_species(name)
    for key, want in PUBLISHED[name].items():
        got = _value(params, key)
        assert got == want, f"{name}: {key} = {got!r}, the paper's table says {want!r}"
    assert "Weber" in params.species["source"]


def test_every_shipped_species_loads_and_names_its_source():
    names = species_names()
    for extra in ("norway_spruce", "silver_fir", "european_beech", "scots_pine",
                  "sycamore_maple"):
        assert extra in names
    for name in names:
        p = load_species(name)
        assert p.name == name and len(p.species["source"]) > 40


def test_parameters_round_trip_through_toml(tmp_path):
    for name in ("weeping_willow", "norway_spruce"):
        p = load_species(name)
        again = load_species(write_species(tmp_path / f"{name}.toml", p))
        assert again == p
        assert params_to_dict(again) == params_to_dict(p)


@pytest.mark.parametrize("edit, field", [
    (lambda d: d["tree"].pop("Ratio"), "tree.Ratio"),
    (lambda d: d["level"]["1"].__setitem__("Length", -0.3), "level.1.Length"),
    (lambda d: d["tree"].__setitem__("Levels", 5), "tree.Levels"),
    (lambda d: d["level"].__setitem__("4", dict(d["level"]["3"])), "level.4"),
    (lambda d: d["tree"].__setitem__("LeafShape", "hexagon"), "tree.LeafShape"),
    (lambda d: d["level"]["2"].pop("CurveRes"), "level.2.CurveRes"),
    (lambda d: d["appearance"].__setitem__("bark", [0.5, 2.0, 0.1]), "appearance.bark"),
])
def test_a_missing_or_out_of_range_field_is_named(edit, field):
    d = params_to_dict(load_species("quaking_aspen"))
    edit(d)
    with pytest.raises(InputError) as err:
        parse_params(d, path="aspen.toml")
    assert err.value.field == field and "aspen.toml" in str(err.value)


def test_unknown_species_is_refused_with_the_known_names():
    with pytest.raises(InputError, match="unknown species 'baobab'.*quaking_aspen"):
        load_species("baobab")


def test_shape_ratios_and_taper_follow_the_paper():
    r = np.linspace(0, 1, 11)
    np.testing.assert_allclose(shape_ratio(1, r), 0.2 + 0.8 * np.sin(np.pi * r))
    np.testing.assert_allclose(shape_ratio(6, r), 1 - 0.8 * r)
    assert shape_ratio(7, 0.7) == pytest.approx(1.0) and shape_ratio(3, 0.2) == 1.0
    z = np.linspace(0, 1, 101)
    np.testing.assert_allclose(taper_radius(1.0, 10.0, z, 1.0), 1 - z)       # a cone
    np.testing.assert_allclose(taper_radius(1.0, 10.0, z, 0.5), 1 - 0.5 * z)
    bulges = taper_radius(0.5, 10.0, z, 3.0)                                  # periodic
    assert bulges.max() <= 0.5 + 1e-12 and (np.diff(np.sign(np.diff(bulges))) != 0).sum() > 4


@pytest.fixture(scope="module")
def beech():
    return grow(load_species("european_beech"), height=8.0, rng=np.random.default_rng(4))


def test_the_tree_has_the_height_asked_and_leaves_in_its_crown(beech):
    sk = beech.skeleton
    assert sk.points[:, 2].max() == pytest.approx(8.0)
    assert sk.points[:, 2].min() == pytest.approx(0.0, abs=1e-9)
    assert set(np.unique(sk.level)) == {0, 1, 2} and len(beech.leaves) > 500
    z = beech.leaves.position[:, 2]
    assert np.percentile(z, 5) > 0.3 * 8.0          # the clean bole (BaseSize 0.4) has none


def test_the_qsm_is_a_tree_and_round_trips_through_csv(beech, tmp_path):
    q = tree_qsm(beech)
    check_qsm(q)
    assert q.parent[0] == 0 and np.all(q.length > 0) and np.all(q.radius > 0)
    np.testing.assert_allclose(np.linalg.norm(q.axis, axis=1), 1.0)
    back = read_qsm_csv(write_qsm_csv(tmp_path / "t.qsm.csv", q))
    for name in ("id", "parent", "extension", "branch", "branch_order"):
        np.testing.assert_array_equal(getattr(back, name), getattr(q, name))
    for name in ("start", "axis", "length", "radius"):
        np.testing.assert_array_equal(getattr(back, name), getattr(q, name))
    # a branch's first cylinder starts where its parent cylinder ends
    pidx = q.parent_index()
    has = pidx >= 0
    np.testing.assert_allclose(q.start[has], q.end[pidx[has]], atol=1e-6)


def _qsm(parent):
    n = len(parent)
    return QSM(np.arange(1, n + 1), np.array(parent), np.zeros(n, int), np.ones(n, int),
               np.zeros(n, int), np.zeros((n, 3)), np.tile([0.0, 0.0, 1.0], (n, 1)),
               np.ones(n), np.full(n, 0.1))


@pytest.mark.parametrize("parent, what", [([0, 1, 4, 3], "cycle"), ([0, 0, 1], "one root"),
                                          ([0, 1, 7], "no cylinder")])
def test_parents_that_do_not_form_a_tree_are_refused(parent, what):
    with pytest.raises(InputError, match=what) as err:
        check_qsm(_qsm(parent))
    assert err.value.field == "parent"


@pytest.mark.parametrize("name", ["european_beech", "quaking_aspen", "norway_spruce",
                                  "weeping_willow"])
def test_leonardo_allometry_and_envelope_hold_on_small_trees(name):
    p = load_species(name)
    heights = (3.0, 5.0, 8.0, 12.0)
    dbhs, deltas = [], None
    for h in heights:
        t = grow(p, height=h, rng=np.random.default_rng(int(h)))
        q = tree_qsm(t)
        dbhs.append(laws.dbh(q))
        if h == 8.0:
            deltas = laws.leonardo_exponents(q)
            corr, _ = laws.species_envelope(q, p, leaves=t.leaves.position)
            tp = laws.taper(q)
    assert len(deltas) > 50 and 1.8 <= np.median(deltas) <= 2.3        # Eloy (2011)
    assert 0.45 <= laws.allometric_exponent(heights, dbhs) <= 0.8
    assert tp["monotone"] > 0.95 and tp["per_metre"] > 0
    assert corr >= 0.9


def test_leonardo_fit_recovers_a_known_exponent():
    # a parent of radius 1 with two children whose radii satisfy d^2.5 = d1^2.5 + d2^2.5
    r1 = 0.7
    r2 = (1 - r1 ** 2.5) ** (1 / 2.5)
    q = QSM(np.array([1, 2, 3]), np.array([0, 1, 1]), np.array([2, 0, 0]),
            np.array([1, 1, 2]), np.array([0, 0, 1]), np.zeros((3, 3)),
            np.tile([0.0, 0.0, 1.0], (3, 1)), np.ones(3), np.array([1.0, r1, r2]))
    assert laws.leonardo_exponents(q) == pytest.approx([2.5], abs=1e-6)


def test_seasons_and_leaf_cards(beech):
    rng = np.random.default_rng
    summer = tree_mesh(beech, rng=rng(1))
    winter = tree_mesh(beech, rng=rng(1), season="winter")
    autumn = tree_mesh(beech, rng=rng(1), season="autumn")
    cards = tree_mesh(beech, rng=rng(1), lod="cards")
    leaf = 4
    assert not np.any(winter.labels == leaf) and np.any(summer.labels == leaf)
    red = lambda m: m.colors[m.labels == leaf][:, 0].mean()  # noqa: E731
    assert red(autumn) > red(summer) + 0.15          # copper-brown against green
    assert len(cards.triangles) < 0.3 * len(summer.triangles)
    assert set(np.unique(summer.labels)) == {0, 1, 2, 4}


def _cli(args):
    from scanamp.cli import main

    return main(args)


def test_same_seed_same_bytes_and_the_outputs(tmp_path):
    outs = []
    for k, seed in enumerate((5, 5, 6)):
        out = tmp_path / f"t{k}"
        assert _cli(["procgen", "tree", "--species", "lombardy_poplar", "--height", "6",
                     "--seed", str(seed), "--out", str(out), "--no-preview"]) == 0
        outs.append(out)
    for name in ("tree.ply", "tree.qsm.csv"):
        assert (outs[0] / name).read_bytes() == (outs[1] / name).read_bytes()
        assert (outs[0] / name).read_bytes() != (outs[2] / name).read_bytes()
    from core.io.mesh import read_labeled_mesh

    m = read_labeled_mesh(outs[0] / "tree.ply")
    assert m["names"][0] == "trunk" and m["names"][4] == "leaf"
    assert {0, 1, 2, 4} <= set(np.unique(m["labels"]).tolist())


def _bad_file(tmp_path, edit):
    d = params_to_dict(load_species("sassafras"))
    edit(d)
    import tomli_w

    path = tmp_path / "bad.toml"
    path.write_bytes(tomli_w.dumps(d).encode())
    return path


@pytest.mark.parametrize("species, field", [
    ("baobab", "--species"),
    (lambda d: d["tree"].pop("Scale"), "tree.Scale"),
    (lambda d: d["level"]["1"].__setitem__("Length", -1.0), "level.1.Length"),
    (lambda d: d["tree"].__setitem__("Levels", 6), "tree.Levels"),
])
def test_cli_bad_species_exit_2_naming_file_and_field(tmp_path, capsys, species, field):
    if callable(species):
        species = str(_bad_file(tmp_path, species))
    out = tmp_path / "out"
    assert _cli(["procgen", "tree", "--species", species, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error:") and field in err[0]
    if species.endswith(".toml"):
        assert species in err[0]
    assert not out.exists()


def test_cli_tree_laws_refuses_a_qsm_that_is_no_tree(tmp_path, capsys):
    bad = tmp_path / "loop.qsm.csv"
    q = _qsm([0, 1, 4, 3])
    rows = ["id,parent,extension,branch,branch_order,start_x,start_y,start_z,axis_x,axis_y,"
            "axis_z,length,radius"]
    rows += [f"{i},{p},0,1,0,0,0,0,0,0,1,1,0.1" for i, p in zip(q.id, q.parent, strict=False)]
    bad.write_text("\n".join(rows) + "\n")
    out = tmp_path / "laws.json"
    assert _cli(["procgen", "tree-laws", str(bad), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error:") and str(bad) in err and "parent" in err
    assert not out.exists()


@pytest.mark.parametrize("name, rotate", [("european_beech", 137.5), ("sycamore_maple", 90.0),
                                          ("quaking_aspen", 140.0)])
def test_divergence_between_successive_limbs_is_the_species_rotation(name, rotate):
    # spiral phyllotaxis at the golden angle (beech), decussate pairs (sycamore), the
    # paper's 140 (aspen); RotateV and the stem's curvature spread it a little
    q = tree_qsm(grow(load_species(name), height=10.0, rng=np.random.default_rng(1)))
    assert np.median(laws.divergence_angles(q)) == pytest.approx(rotate, abs=8.0)


def test_a_negative_curve_v_grows_a_helix():
    d = params_to_dict(load_species("lombardy_poplar"))
    d["level"]["0"].update(CurveV=-20.0, CurveRes=16)
    t = grow(parse_params(d), height=10.0, rng=np.random.default_rng(0))
    trunk = t.skeleton.points[t.skeleton.ptr[0]:t.skeleton.ptr[1]]
    xy = trunk[:, :2] - trunk[:, :2].mean(0)
    r = np.linalg.norm(xy, axis=1)
    turn = np.diff(np.unwrap(np.arctan2(xy[:, 1], xy[:, 0])))
    # a circle about the axis, walked one way: one turn over the stem
    assert r.std() < 0.1 * r.mean() and np.all(turn > 0)
    assert turn.sum() == pytest.approx(2 * np.pi, rel=0.1)
    # the helix leans |CurveV| off the vertical: rise over run = 1 / tan(20 deg)
    step = np.diff(trunk, axis=0)
    lean = np.degrees(np.arctan2(np.linalg.norm(step[:, :2], axis=1), step[:, 2]))
    assert np.median(lean) == pytest.approx(20.0, abs=1.0)


def test_cli_refuses_a_height_out_of_range(tmp_path, capsys):
    out = tmp_path / "out"
    assert _cli(["procgen", "tree", "--species", "palm", "--height", "-3",
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "height" in err[0] and not out.exists()


def test_pruning_keeps_the_stems_inside_the_envelope():
    from procgen.weber_penn.shapes import inside_envelope

    share = {}
    for ratio in (1.0, 0.0):
        d = params_to_dict(load_species("weeping_willow"))
        d["tree"]["PruneRatio"] = ratio
        p = parse_params(d)
        t = grow(p, rng=np.random.default_rng(0))
        sk = t.skeleton
        branches = sk.level[sk.stem_of_point()] >= 1
        scale = sk.stem_length[0] / p.levels[0]["Length"]   # the tree's scale, as grown
        share[ratio] = inside_envelope(sk.points[branches], scale=scale,
                                       base_size=p["BaseSize"], prune=p.tree).mean()
    assert share[1.0] > 0.999 and share[0.0] < 0.9


def test_leaf_colour_varies_within_a_crown_and_between_trees():
    p = load_species("quaking_aspen")
    means, spreads, tops = [], [], []
    for seed in (1, 2, 3):
        t = grow(p, height=6.0, rng=np.random.default_rng(seed))
        m = tree_mesh(t, rng=np.random.default_rng(seed))
        leaf = m.labels == 4
        c, z = m.colors[leaf], m.vertices[leaf, 2]
        means.append(c.mean(0))
        spreads.append(c.std(0).mean())
        tops.append(c[z > np.percentile(z, 80)].mean() - c[z < np.percentile(z, 20)].mean())
    assert min(spreads) > 0.01                                   # leaf to leaf
    assert np.ptp(np.array(means), axis=0).max() > 0.01          # tree to tree
    assert min(tops) > 0                                         # lighter at the top


def test_flare_widens_the_trunk_base_and_lobes_ripple_it():
    from procgen.weber_penn.shapes import flare_factor

    p = load_species("ca_black_oak")                  # Flare 1.2, 5 lobes of depth 0.1
    t = grow(p, height=6.0, rng=np.random.default_rng(2))
    q = tree_qsm(t)
    r0 = q.radius[0]
    own = t.skeleton.radius[0]                         # the pipe radius, before the flare
    assert r0 == pytest.approx(own * flare_factor(0.0, p["Flare"]))
    assert flare_factor(0.0, 1.2) == pytest.approx(1 + 1.2 * 0.99)
    m = tree_mesh(t, rng=np.random.default_rng(0))
    ring = m.vertices[:20 * 1]                         # the trunk's first ring (20 sides)
    rr = np.linalg.norm(ring[:, :2] - t.skeleton.points[0, :2], axis=1)
    assert rr.max() / rr.min() == pytest.approx(1.1 / 0.9, rel=0.05)


def test_conifers_carry_needle_tufts():
    from procgen.weber_penn.appearance import NEEDLES_PER_TUFT

    t = grow(load_species("norway_spruce"), height=5.0, rng=np.random.default_rng(0))
    m = tree_mesh(t, rng=np.random.default_rng(0))
    needles = (m.labels[m.triangles[:, 0]] == 4).sum()
    assert needles == NEEDLES_PER_TUFT * len(t.leaves) > 0


def test_a_stand_instances_its_templates_at_the_heights_asked():
    from procgen.weber_penn import grow_stand

    pos = np.array([[0.0, 0.0, 0.0], [10.0, 0.0, 1.0], [0.0, 10.0, 0.0]])
    heights = np.array([5.0, 6.0, 4.0])
    stand = grow_stand(["lombardy_poplar", "lombardy_poplar", "palm"], pos, heights,
                       rng=np.random.default_rng(0), variants=2)
    mesh = stand.mesh()
    assert len(stand.templates) == 4 and len(stand.template) == 3
    for k in range(3):
        m = stand.templates[stand.template[k]]
        start = sum(len(stand.templates[j].vertices) for j in stand.template[:k])
        v = mesh.vertices[start:start + len(m.vertices)]
        wood = m.labels != 4
        top = v[wood, 2].max() - pos[k, 2]
        assert top == pytest.approx(heights[k], rel=1e-9)      # the skeleton's top, scaled


def _leaves_whole_array(tree, rng):
    """The leaves as one vectorised expression over every leaf at once: the formula the
    blockwise builder must reproduce to the bit."""
    from procgen.weber_penn.appearance import NEEDLES_PER_TUFT, leaf_outline
    from procgen.weber_penn.params import leaf_shape_name
    lv = tree.leaves
    shape = leaf_shape_name(tree.params["LeafShape"])
    side = np.cross(lv.normal, lv.axis)
    if shape == "needles":
        k = NEEDLES_PER_TUFT
        ang = 2 * np.pi * (np.arange(k) / k)[None, :] + rng.uniform(0, 2 * np.pi, (len(lv), 1))
        spread = np.radians(40) * min(tree.params["LeafScaleX"], 1.5)
        d = (np.cos(spread) * lv.axis[:, None, :]
             + np.sin(spread) * (np.cos(ang)[..., None] * side[:, None, :]
                                 + np.sin(ang)[..., None] * lv.normal[:, None, :]))
        tip = lv.position[:, None, :] + lv.length[:, None, None] * d
        wid = 0.004 * (np.cos(ang)[..., None] * lv.normal[:, None, :]
                       - np.sin(ang)[..., None] * side[:, None, :])
        verts = np.stack([lv.position[:, None, :] + wid, lv.position[:, None, :] - wid, tip],
                         2).reshape(-1, 3)
        return verts, np.arange(len(verts)).reshape(-1, 3)
    outline = leaf_outline(shape)
    k = len(outline)
    pts2 = np.concatenate([[[0.0, 0.5]], outline])
    x = pts2[:, 0][None, :, None] * lv.width[:, None, None] * side[:, None, :]
    y = pts2[:, 1][None, :, None] * lv.length[:, None, None] * lv.axis[:, None, :]
    verts = (lv.position[:, None, :] + x + y).reshape(-1, 3)
    fan = np.stack([np.zeros(k, int), np.arange(1, k + 1), np.arange(2, k + 2)], 1)
    fan[-1, 2] = 1
    return verts, (np.arange(len(lv))[:, None, None] * (k + 1) + fan[None]).reshape(-1, 3)


@pytest.mark.parametrize("name", ["black_tupelo", "scots_pine"])
def test_leaves_built_in_blocks_are_the_whole_array_formula_to_the_bit(name, monkeypatch):
    # blocks of 13 leaves, the last one partial: every leaf and every index must land where
    # the whole-array formula puts it, with the same bits
    from procgen.weber_penn import appearance
    monkeypatch.setattr(appearance, "LEAF_BLOCK", 13)
    tree = grow(load_species(name), height=5.0, rng=np.random.default_rng(4))
    assert len(tree.leaves) % 13 != 0 and len(tree.leaves) > 50
    mesh = tree_mesh(tree, rng=np.random.default_rng(9))
    rng = np.random.default_rng(9)
    rng.integers(2 ** 31)                       # the bark's seed
    rng.normal(size=3), rng.normal(size=len(tree.leaves))  # the leaf colours' draws
    verts, tris = _leaves_whole_array(tree, rng)
    leaf = mesh.labels == 4
    n0 = int(np.argmax(leaf))
    assert leaf[n0:].all() and leaf.sum() == len(verts)
    assert mesh.vertices[n0:].tobytes() == verts.tobytes()
    tail = mesh.triangles[len(mesh.triangles) - len(tris):]
    np.testing.assert_array_equal(tail, tris + n0)
    assert mesh.triangles.dtype == np.int64 and mesh.colors.shape == mesh.vertices.shape
