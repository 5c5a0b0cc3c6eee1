"""What a study run stores so that sizing never refits: ``weights.json`` next to ``fits/*.nc``.

``weights.json`` (format :data:`FORMAT`) records, per law, its fit file, the diagnostics verdict,
whether the evidence estimators agreed (shown, never a reason to leave a law out of sizing),
every weight the study computed (keys as in :attr:`bayesfric.study.outcome.LawOutcome.weights`:
``"stacking LOO"``, ``"stacking <blocked label>"`` for every blocked scheme ...), why a weighting
left the law out, the law's measured miss on every blocked scheme
(:mod:`bayesfric.sizing.calibration`) and its extrapolation penalties; plus the study's blocked
schemes (axis, direction, ``|x|`` or not). Which weights answer a question is chosen per
question from its direction (:mod:`bayesfric.sizing.basis`). ``bayesfric size STUDY.toml``
reads the record back as data; the exclusion reason is derived from its booleans
(:func:`exclusion`), never parsed from text.
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
from bayesfric.sizing.basis import LOO
from bayesfric.sizing.calibration import Miss, Scheme, measure_miss
from bayesfric.sizing.compute import LawSource
from bayesfric.sizing.points import SizingError

__all__ = ["RECORD", "FORMAT", "schemes_of", "weights_record", "write_record", "read_record", "exclusion",
           "record_schemes", "sources"]

#: File name of the record in a report folder.
RECORD = "weights.json"
#: Version of the record's layout (2: blocked schemes, misses and penalties per law).
FORMAT = 2


def _number(x: Any) -> float | None:
    return float(x) if isinstance(x, int | float) and math.isfinite(x) else None


def schemes_of(outcome) -> list[Scheme]:
    """The study's blocked extrapolation schemes as sizing reads them (leave-future-out ones are
    not envelope extrapolations and are left out); ``|x|`` where the input has both signs, as
    :func:`bayesfric.compare.blocked_masks` blocks it."""
    out = []
    for label, spec in zip(outcome.blocked, outcome.study.blocked, strict=True):
        if spec.future:
            continue
        values = outcome.data[spec.axis].values
        out.append(Scheme(label, spec.axis, spec.direction, bool((values < 0).any() and (values > 0).any())))
    return out


def _misses(w, data, schemes: Sequence[Scheme]) -> dict[str, dict]:
    out = {}
    for scheme in schemes:
        if scheme.label in w.cv and (miss := measure_miss(w.cv[scheme.label], data, scheme)) is not None:
            out[scheme.label] = miss.to_json()
    return out


def weights_record(outcome) -> dict[str, Any]:
    """The record of a :class:`~bayesfric.study.outcome.StudyOutcome` (after its weights)."""
    schemes = schemes_of(outcome)
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
            "misses": _misses(w, outcome.data, schemes),
            "penalties": {k: _number(v) for k, v in w.penalty.items()},
        })
    return {
        "format": FORMAT,
        "study": outcome.study.name,
        "dataset": str(outcome.data.attrs.get("name", "")),
        "data_hash": str(outcome.data.attrs.get("data_hash", "")),
        "schemes": [s.to_json() for s in schemes],
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
    """Why sizing may not use a law's predictions (None: it may): its full fit failed the
    diagnostics gate. Only a reason about its predictions counts: an unreliable *evidence*
    estimate removes a law from the evidence ranking and nothing else."""
    if entry.get("diagnostics_passed", False):
        return None
    problems = "; ".join(entry.get("diagnostics_problems") or [])
    return "failed the diagnostics gate" + (f" ({problems})" if problems else "")


def record_schemes(record: dict[str, Any]) -> list[Scheme]:
    """The blocked schemes of a record (:func:`schemes_of`)."""
    return [Scheme(str(s["label"]), str(s["axis"]), str(s["direction"]), bool(s["use_abs"]))
            for s in record.get("schemes") or []]


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
        stored = entry.get("weights") or {}
        weights = {(LOO if key == "stacking LOO" else key.removeprefix("stacking ")): float(v)
                   for key, v in stored.items() if key.startswith("stacking ") and v is not None}
        notes = "; ".join(f"{k}: {v}" for k, v in (entry.get("weight_exclusions") or {}).items())
        misses = {k: Miss.from_json(v) for k, v in (entry.get("misses") or {}).items()}
        penalties = {k: float(v) for k, v in (entry.get("penalties") or {}).items() if v is not None}
        out.append(LawSource(name, fit, weights, exclusion(entry), notes, misses, penalties))
    return out
