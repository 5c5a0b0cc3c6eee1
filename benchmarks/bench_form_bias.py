"""How large the form error of sizing's calibration test is, against what the data show of it.

Usage::

    .venv/bin/python benchmarks/bench_form_bias.py

The calibration test (``tests/test_sizing_calibration.py``) fits laws linear in their
coefficients to 30 speeds in 0.1–2 rad/s (noise sd 0.3) and asks at 2.5–4 rad/s. For each truth
shape this prints, exactly (no simulation): the bias of the least-squares line (Coulomb + viscous,
the candidate whose form is closest) at 2.5 / 3 / 4 rad/s, that bias over the line's sampling sd
there, and the t-statistic of a quadratic term fitted on the data (how clearly the data show the
curvature). A calibrated band covers a truth at a point in 85–97 % of replicates only if the
model-form allowance tracks that deterministic bias to about ±20 %; the last column says how well
the data measure what the allowance would have to extrapolate (issue 47 item 6).
"""

from __future__ import annotations

import numpy as np

from tests.test_sizing_calibration import SIGMA, SPEEDS, TRUTHS

AT = (2.5, 3.0, 4.0)


def rows() -> list[tuple[str, list[float], list[float], float]]:
    """(truth, bias at AT, bias / sampling sd at AT, curvature t on the data) per truth shape."""
    x = np.c_[np.ones_like(SPEEDS), SPEEDS]
    cov = np.linalg.inv(x.T @ x)
    x2 = np.c_[x, SPEEDS**2]
    cov2 = np.linalg.inv(x2.T @ x2)
    out = []
    for name, truth in TRUTHS.items():
        y = truth(SPEEDS)
        beta = cov @ x.T @ y
        bias = [float(beta[0] + beta[1] * v - truth(v)) for v in AT]
        sd = [SIGMA * float(np.sqrt(np.array([1.0, v]) @ cov @ np.array([1.0, v]))) for v in AT]
        quad = (cov2 @ x2.T @ y)[2] / (SIGMA * np.sqrt(cov2[2, 2]))
        out.append((name, bias, [b / s for b, s in zip(bias, sd, strict=True)], float(quad)))
    return out


def main() -> None:
    print(f"{'truth':28s} {'bias at 2.5 / 3 / 4 rad/s':>26s} {'bias / sd':>18s} {'curvature t':>12s}")
    for name, bias, ratio, quad in rows():
        print(f"{name:28s} {' / '.join(f'{b:+.2f}' for b in bias):>26s} "
              f"{' / '.join(f'{r:+.0f}' for r in ratio):>18s} {quad:+12.1f}")


if __name__ == "__main__":
    main()
