"""Scan -> reconstruct round trip on every thesis object, against the thesis's tables.

Targets (issue 2): height and rim radius within 3 %, volume within 10 % with the better
inner model, where the thesis reports mean errors of 11.2 %, 7.0 % and 39.7 %.
"""

import numpy as np
import pytest

from pour_gym.mesh.modelgen import generate_model
from pour_gym.objects import OBJECT_NAMES

THESIS_MEAN_ERROR = {"height": 0.1122, "rim_radius": 0.0702, "volume": 0.3966}
TARGET_MEAN = {"height": 0.03, "rim_radius": 0.03, "volume": 0.10}


@pytest.fixture(scope="module")
def reports():
    return {name: generate_model(name).report for name in OBJECT_NAMES}


@pytest.mark.slow
@pytest.mark.parametrize("name", OBJECT_NAMES)
def test_round_trip_per_object(reports, name):
    report = reports[name]
    assert report["n_points"] > 20000
    for model in ("thesis", "offset"):
        m = report["models"][model]
        assert m["watertight"], f"{name}/{model} mesh has holes"
        assert m["chamfer_distance"] < 0.0025
    errors = report["models"]["offset"]["errors"]
    assert errors["height"]["rel_error"] <= 0.03
    assert errors["rim_radius"]["rel_error"] <= 0.03
    # Per object the volume is allowed a little more than the mean target: the model
    # assumes 4 mm walls and the bowls have 5 mm.
    assert errors["volume"]["rel_error"] <= 0.12
    # The report says what the thesis itself got for this object.
    assert report["thesis"]["volume"]["rel_error"] > 0.2


def mean_error(reports, model, quantity):
    return float(
        np.mean([r["models"][model]["errors"][quantity]["rel_error"] for r in reports.values()])
    )


@pytest.mark.slow
@pytest.mark.parametrize("quantity", ["height", "rim_radius", "volume"])
def test_mean_errors_meet_targets_and_beat_the_thesis(reports, quantity):
    offset = mean_error(reports, "offset", quantity)
    thesis_model = mean_error(reports, "thesis", quantity)
    assert offset <= TARGET_MEAN[quantity]
    assert thesis_model < THESIS_MEAN_ERROR[quantity]


@pytest.mark.slow
def test_offset_model_holds_volume_better_than_the_thesis_model(reports):
    assert mean_error(reports, "offset", "volume") < mean_error(reports, "thesis", "volume")
