"""The verdict 'no law extrapolates' (issue #28): stated before any recommendation when every law
with a penalty on a blocked fold loses more than NO_EXTRAPOLATION nats per held-out point."""

from __future__ import annotations

import pandas as pd

from bayesfric.report.findings import no_law_extrapolates
from bayesfric.sizing.basis import NO_EXTRAPOLATION


def _table(penalties: dict[str, float], scheme: str = "train low, score high") -> pd.DataFrame:
    rows = [(law, "penalty", scheme, value, 0.5, True, "") for law, value in penalties.items()]
    rows.append(("skipped_law", "elpd_loo", "", -10.0, 1.0, False, "the fit failed the gate"))
    return pd.DataFrame(rows, columns=["law", "metric", "scheme", "estimate", "se", "reliable", "reason"])


BLOCKED = ["train low, score high"]


def test_every_law_losing_more_than_the_threshold_is_a_verdict():
    # the skipped law has no penalty: it predicts nothing
    verdict = no_law_extrapolates(BLOCKED, _table({"a": NO_EXTRAPOLATION + 8.2, "b": NO_EXTRAPOLATION + 0.1}))
    assert verdict is not None and verdict.warning
    assert verdict.text.startswith("NO LAW EXTRAPOLATES along 'train low, score high'")
    assert "the least, b," in verdict.text


def test_one_law_under_the_threshold_is_no_verdict():
    assert no_law_extrapolates(BLOCKED, _table({"a": NO_EXTRAPOLATION + 8.0, "b": NO_EXTRAPOLATION - 0.5})) is None
    assert no_law_extrapolates(BLOCKED, _table({})) is None  # no penalty at all: nothing to say
