"""The contour family at a tiny size: the transfer table, the pooled learning, the files."""

import json

import numpy as np
import pytest

from ftdrake.config.contour import HoleConfig
from ftdrake.errors import ConfigError
from ftdrake.experiments.contour import ContourPlan
from ftdrake.experiments.contour_family import (
    MEMBERS,
    POOL,
    FamilyPlan,
    family_plan,
    run_contour_family,
)


def _hole(**kw) -> HoleConfig:
    return HoleConfig(**{"diameter_m": 0.004, "speed_m_s": 0.05, "rest_s": 0.05, **kw})


def _tiny() -> FamilyPlan:
    contour = ContourPlan(iterations=1, hole=_hole(), methods=("timed", "contour", "ilc"),
                          max_points=20, optimize_points=30).with_seed(2)
    return FamilyPlan(contour,
                      members={"fast": _hole(speed_m_s=0.08),
                               "reversed": _hole(direction="cw")},
                      pool={"earlier": _hole(diameter_m=0.005, offset_m=[0.002, 0.0, 0.0])},
                      curve_contour="fast", name="tiny")


def test_family_transfer_table_and_learning_curve(tmp_path):
    dut = run_contour_family(plan=_tiny(), out_dir=tmp_path, progress=False)
    transfer = json.loads((tmp_path / "transfer.json").read_text())
    assert set(transfer) == {"fast", "reversed"}
    for name, kept in transfer.items():
        assert set(kept) == {"two_part_timed", "two_part_contour", "ilc", "pooled"}
        rms = dut["radial_rms_mm"][name]
        for method, k in kept.items():  # K = RMS without learning ÷ RMS with the correction
            assert k == pytest.approx(rms["none"] / rms[method], rel=1e-12)
    curve = json.loads((tmp_path / "learning_curve.json").read_text())
    assert curve["contour"] == "fast"
    assert curve["contours_learned_from"] == [0, 1, 2]
    assert curve["pooled"] == ["none", "base", "earlier"]
    assert curve["radial_rms_mm"][0] == dut["radial_rms_mm"]["fast"]["none"]
    # The pooled column on the curve's contour is the last point of the curve.
    assert curve["radial_rms_mm"][-1] == dut["radial_rms_mm"]["fast"]["pooled"]
    np.testing.assert_allclose(curve["improvement"],
                               curve["radial_rms_mm"][0] / np.array(curve["radial_rms_mm"]))
    # Learned on the base hole at 50 mm/s, the corrections still help at 80 mm/s.
    assert transfer["fast"]["two_part_timed"] > 1.0 and transfer["fast"]["pooled"] > 1.0
    # The pooled GPs stay bounded: max_points rows kept of everything pooled.
    size = dut["pool_size"]
    assert size["contours"] == ["base", "earlier"]
    assert size["torque_rows_kept"] == size["reference_rows_kept"] == 20
    assert size["torque_rows"] > 20 and size["reference_rows"] > 20
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["family"] == "tiny" and summary["transfer"] == transfer


def test_family_plans_and_their_errors():
    quick = family_plan("quick")
    assert {"speed_60", "reversed"} <= set(quick.members)
    assert quick.curve_contour in quick.members and len(quick.pool) >= 2
    full = family_plan("full", iterations=4, seed=9)
    assert set(full.members) == set(MEMBERS) and set(full.pool) == set(POOL)
    assert full.contour.iterations == 4 and full.contour.tracker.seed == 9
    with pytest.raises(ConfigError, match="--family"):
        family_plan("huge")
    chosen = family_plan("quick", members=["slot_corners", "tilted_x20"])
    assert list(chosen.members) == ["slot_corners", "tilted_x20"]
    assert chosen.curve_contour == "slot_corners" and chosen.pool == quick.pool
    with pytest.raises(ConfigError, match=r"--members: unknown \['nope'\]"):
        family_plan("quick", members=["nope"])
    with pytest.raises(ConfigError, match="both a member and in the pool"):
        FamilyPlan(members={"a": HoleConfig()}, pool={"a": HoleConfig()},
                   curve_contour="a").validate()
    with pytest.raises(ConfigError, match=r"family\.bad\.direction"):
        FamilyPlan(members={"bad": HoleConfig(direction="up")}, pool={},
                   curve_contour="bad").validate()
