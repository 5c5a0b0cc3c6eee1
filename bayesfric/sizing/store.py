"""What a study run stores so that sizing never refits: ``weights.json`` next to ``fits/*.nc``.

``weights.json`` (format :data:`FORMAT`) records, per law, its fit file, the diagnostics verdict,
whether the evidence estimators agreed, every weight the study computed (keys as in
:attr:`bayesfric.study.outcome.LawOutcome.weights`: ``"stacking LOO"``, ``"stacking <first
blocked label>"`` ...) and why a weighting left the law out; plus which weights sizing averages
by (``average_by``: stacking on the first blocked extrapolation scheme, else LOO stacking) and
which it shows beside them (``shown_beside``). ``bayesfric size STUDY.toml`` reads it back as
data; the exclusion reasons are derived from its booleans (:func:`exclusion`), never parsed
from text.
"""

from __future__ import annotations

import json
import math
import os
import secrets
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import xarray as xr

from bayesfric.inference import load_fit
from bayesfric.sizing.compute import LawSource
from bayesfric.sizing.points import SizingError

__all__ = ["RECORD", "FORMAT", "weights_record", "write_record", "read_record", "exclusion", "sources"]

#: File name of the record in a report folder.
RECORD = "weights.json"
#: Version of the record's layout.
FORMAT = 1


def _number(x: Any) -> float | None:
    return float(x) if isinstance(x, int | float) and math.isfinite(x) else None


def weights_record(outcome) -> dict[str, Any]:
    """The record of a :class:`~bayesfric.study.outcome.StudyOutcome` (after its weights)."""
    blocked = f"stacking {outcome.blocked[0]}" if outcome.blocked else None
    loo = "stacking LOO" if outcome.study.loo else None
    laws = []
    for w in outcome.laws:
        laws.append({
            "law": w.name,
            "fit": f"fits/{w.fit_file.name}",
            "diagnostics_passed": bool(w.verdict.passed),
            "diagnostics_problems": list(w.verdict.problems),
            "evidence_agree": bool(w.evidence_agree),
            "evidence_disagreement": _number(w.agreement.difference if w.agreement is not None else math.nan),
            "weights": {k: _number(v.value) for k, v in w.weights.items()},
            "weight_exclusions": {k: v.excluded for k, v in w.weights.items() if v.excluded},
        })
    return {
        "format": FORMAT,
        "study": outcome.study.name,
        "dataset": str(outcome.data.attrs.get("name", "")),
        "data_hash": str(outcome.data.attrs.get("data_hash", "")),
        "average_by": blocked or loo,
        "shown_beside": loo if blocked else None,
        "laws": laws,
    }


def write_record(folder: Path, record: dict[str, Any]) -> Path:
    """Write ``folder/weights.json`` atomically (ordinary file modes: the folder is installed later)."""
    path = folder / RECORD
    tmp = folder / f".{RECORD}.{secrets.token_hex(4)}.tmp"
    tmp.write_text(json.dumps(record, indent=1, ensure_ascii=False, allow_nan=False) + "\n", encoding="utf-8")
    os.replace(tmp, path)
    return path


def read_record(folder: Path) -> dict[str, Any]:
    """Read ``folder/weights.json``; a missing, unreadable or foreign file is a :class:`SizingError`."""
    path = folder / RECORD
    if not path.is_file():
        raise SizingError("", f"{path}: missing (the report was written before sizing existed); run the study again")
    try:
        record = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise SizingError("", f"{path}: unreadable ({exc}); run the study again") from None
    if not isinstance(record, dict) or record.get("format") != FORMAT or not isinstance(record.get("laws"), list):
        raise SizingError("", f"{path}: not a bayesfric weights record of format {FORMAT}; run the study again")
    return record


def exclusion(entry: dict[str, Any]) -> str | None:
    """Why sizing leaves a law out (None: it may be used): failed gate, disagreeing evidence."""
    reasons = []
    if not entry.get("diagnostics_passed", False):
        problems = "; ".join(entry.get("diagnostics_problems") or [])
        reasons.append("failed the diagnostics gate" + (f" ({problems})" if problems else ""))
    if not entry.get("evidence_agree", True):
        gap = entry.get("evidence_disagreement")
        reasons.append("evidence estimators disagree" + (f" by {abs(gap):.2f} nat" if gap is not None else ""))
    return "; ".join(reasons) or None


def sources(record: dict[str, Any], folder: Path, laws: Sequence[str] | None = None,
            fits: dict[str, xr.DataTree] | None = None, data_hash: str | None = None,
            selection: str | None = None) -> list[LawSource]:
    """The :class:`LawSource` of every law of the record (in the order of ``laws`` when given).

    Fits come from ``fits`` (in memory, the runner) or from ``folder/fits/*.nc``.

    Raises
    ------
    SizingError
        A law of ``laws`` has no entry (the study changed since it ran), a fit file is missing or
        unreadable, or a fit was made from other data than ``data_hash`` or another row
        ``selection`` (the data's ``selection`` attr).
    """
    entries = {e.get("law"): e for e in record["laws"] if isinstance(e, dict)}
    names = list(laws) if laws is not None else list(entries)
    missing = [n for n in names if n not in entries]
    if missing:
        raise SizingError("", f"{folder}: the report has no fit of {', '.join(missing)} (the study's laws changed "
                              "since it ran); run the study again")
    average_by, beside = record.get("average_by"), record.get("shown_beside") or "stacking LOO"
    out = []
    for name in names:
        entry = entries[name]
        if fits is not None and name in fits:
            fit = fits[name]
        else:
            path = folder / str(entry.get("fit", ""))
            if not path.is_file() or path.resolve().parent != (folder / "fits").resolve():
                raise SizingError("", f"{path}: fit of {name} missing from the report; run the study again")
            try:
                fit = load_fit(path)
            except (OSError, ValueError) as exc:
                raise SizingError("", f"{path}: unreadable fit ({exc}); run the study again") from None
        if data_hash and fit.attrs.get("data_hash") not in (None, "", data_hash):
            raise SizingError("", f"{folder}: the fit of {name} was made from other data (hash "
                                  f"{fit.attrs.get('data_hash')}, the study's data now {data_hash}); "
                                  "run the study again")
        if selection is not None and str(fit.attrs.get("data_selection", "")) != selection:
            raise SizingError("", f"{folder}: the fit of {name} was made from another row selection "
                                  f"({fit.attrs.get('data_selection') or 'all rows'}; the study now selects "
                                  f"{selection or 'all rows'}); run the study again")
        weights = entry.get("weights") or {}

        def weight(key, weights=weights):
            value = weights.get(key) if key else None
            return float(value) if value is not None else math.nan

        note = (entry.get("weight_exclusions") or {}).get(average_by, "") if average_by else ""
        out.append(LawSource(name, fit, weight(average_by), weight(beside), exclusion(entry), note))
    return out
