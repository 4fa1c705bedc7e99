"""Strict JSON (tuner.strict_json): what any parser reads, with the values JSON cannot hold recorded and restored."""
import json
import math
from pathlib import Path

import numpy as np
import pytest

from tuner import strict_json


def test_non_finite_values_become_null_with_their_path_and_come_back():
    doc = {"a": math.inf, "b": [1.0, -math.inf, {"c": math.nan}], "d": np.float64(2.5), "e": (np.int64(3), True),
           "f": np.array([1.0, np.inf]), "g": Path("x/y"), "h": None}
    text = strict_json.dumps(doc, indent=1)
    plain = json.loads(text, parse_constant=lambda c: pytest.fail(c))  # a strict parser reads it
    assert plain["a"] is None and plain["b"][1] is None and plain["b"][2]["c"] is None and plain["f"] == [1.0, None]
    assert plain["non_finite_values"] == {"a": "inf", "b/1": "-inf", "b/2/c": "nan", "f/1": "inf"}
    back = strict_json.loads(text)
    assert back["a"] == math.inf and back["b"][1] == -math.inf and math.isnan(back["b"][2]["c"])
    assert back["f"] == [1.0, math.inf] and back["e"] == [3, True] and back["g"] == "x/y" and back["h"] is None
    assert "non_finite_values" not in back


def test_what_json_cannot_hold_is_refused_not_turned_into_text():
    with pytest.raises(TypeError, match="set"):
        strict_json.dumps({"x": {1, 2}})
    with pytest.raises(ValueError, match="top-level list"):
        strict_json.dumps([1.0, math.inf])
    with pytest.raises(ValueError, match="not strict JSON: Infinity"):
        strict_json.loads('{"x": Infinity}')
