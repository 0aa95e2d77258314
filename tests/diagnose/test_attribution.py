"""Where a residual sits: the block classes named in a finding."""

from __future__ import annotations

import numpy as np
import pandas as pd

from feedlog.diagnose.attribution import where_text


def test_a_class_value_two_classes_share_is_named_once():
    """A rapid is both a move class and a feed class: the phrase names it once, then the next class."""
    table = pd.DataFrame({"move": ["rapid", "line", "line", "line", "rapid", "line"],
                          "feed": ["rapid", "F600", "F600", "F600", "rapid", "F600"],
                          "dominant": ["along X", "along Y", "along Y", "along Y", "along X", "along Y"]})
    residual = np.array([-0.4, -0.01, 0.0, -0.01, -0.5, 0.0])
    text = where_text(table, residual)
    assert text.count("rapid (") == 1
    assert text.startswith("rapid (98 % of the lost time in 2 of 6 segments)")
    assert "along X (98 % of the lost time in 2 of 6 segments)" in text
