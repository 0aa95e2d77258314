"""What nothing explains is shown with its signature: on the pocket, every move after an arc ran at 70 %
of F (the program says F3000 throughout). The report must say the cause is unknown and put the lost time
where it is: after the first arc (Y from 2.5 mm on, program lines 8 on), along X (the long passes), at
the programmed F3000."""

from __future__ import annotations

import numpy as np
import pandas as pd

from feedlog.diagnose.engine import DiagnoseConfig, diagnose
from feedlog.diagnose.summary import summary_lines
from feedlog.diagnose.unexplained import signature
from tests.diagnose.conftest import slower_after_arcs


def test_the_unexplained_residual_has_its_signature_and_no_cause(hidden):
    dx = diagnose(hidden("arcs", edit=slower_after_arcs), "linuxcnc-xyz", config=DiagnoseConfig(learned=False))
    (entry,) = dx.unexplained
    assert entry["cause"] == "unknown"
    sig = entry["signature"]
    assert sig["along"][0]["value"] == "along X" and sig["along"][0]["share"] > 0.8
    assert sig["speeds"][0]["value"] == "F3000" and sig["speeds"][0]["share"] > 0.95
    assert sig["box_mm"]["y"][0] >= 2.5 and sig["lines"][0] >= 8      # nothing before the first arc
    assert any("cause unknown" in line and "signature:" in line for line in summary_lines(dx))


def test_signature_puts_the_residual_where_it_is():
    table = pd.DataFrame({"first_line": np.arange(10), "line": np.arange(1, 11), "x_end_mm": np.arange(10.0),
                          "y_end_mm": np.zeros(10), "dominant": ["along X"] * 5 + ["along Y"] * 5,
                          "feed": ["F1000"] * 5 + ["F3000"] * 5})
    residual = np.array([0, 0, 0, 0, 0, 0, 0, -0.1, -0.1, -0.1])   # time lost on the last three
    sig = signature(table, residual)
    assert sig["lines"] == [7, 10] and sig["box_mm"]["x"] == [7.0, 9.0]
    assert sig["along"][0] == {"value": "along Y", "share": 1.0} and sig["speeds"][0]["value"] == "F3000"
