"""The reconstructed pitch-bearing data set (seed 000) honours every fact it claims (README §1, §4).

The Rothe Erde comparison is evaluated as the paper did (§3.2, Fig. 7): Eq. 15 with the
blade-root bending moment as M_k and F_A = F_R = 0, against the measured means averaged over
speeds; the measured load slope is the 0-6 MNm chord (the slope f1 was matched to, §3.2).
"""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from bayesfric.datasets import load_builtin

DATA = Path(__file__).resolve().parents[2] / "data" / "pitch_bearing"
MU_ROTHE_ERDE = 0.004  # catalogue coefficient assumed in README §2
MOMENTS = np.arange(7.0)


@pytest.fixture(scope="module")
def ds():
    return load_builtin("pitch_bearing")


@pytest.fixture(scope="module")
def blocks(ds):
    """(moment MNm, speed rpm) -> torques in kN·m of that load-speed block."""
    moment = np.round(ds["bending_moment"].values / 1e6, 6)
    speed = np.round(ds["velocity"].values * 30.0 / np.pi, 6)
    torque = ds["torque"].values / 1e3
    return {(m, s): torque[(moment == m) & (speed == s)]
            for m, s in sorted(set(zip(moment, speed, strict=True)))}


@pytest.fixture(scope="module")
def means(blocks):
    """Per moment: the mean over speeds of the block means (Fig. 7, averaged over speeds)."""
    return np.array([np.mean([v.mean() for (m, _), v in blocks.items() if m == mm])
                     for mm in MOMENTS])


def _generator():
    spec = importlib.util.spec_from_file_location("pitch_bearing_generate", DATA / "generate.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_provenance_units_and_design(ds, blocks):
    assert ds.attrs["provenance"] == "reconstructed"
    assert "reconstructed from Friction torque of wind-turbine pitch bearings" in ds.attrs["title"]
    assert (DATA / "pitch_bearing.csv").read_text().startswith("# RECONSTRUCTED from")
    assert ds["bending_moment"].attrs["original_unit"] == "MN*m"
    assert ds["velocity"].attrs["original_unit"] == "rpm"
    assert ds["torque"].attrs["original_unit"] == "kN*m"
    assert ds.sizes["obs"] <= 300
    assert sorted({m for m, _ in blocks}) == list(MOMENTS)  # 0-6 MNm in 1 MNm steps (§3.2)
    assert all(v.size >= 20 for v in blocks.values())  # at least 20 repetitions (§3.2)
    speeds_deg_s = np.array(sorted({s for _, s in blocks})) * 6.0
    assert speeds_deg_s.max() == pytest.approx(1.04 * 6.0)  # 1.04 rpm (§3.2)
    assert speeds_deg_s.min() >= 3.0 - 1e-9  # Fig. 8: 3 to 6 deg/s
    blade = ds["blade"].values
    zero = ds["bending_moment"].values == 0
    assert set(blade[zero]) == {"without"} and set(blade[~zero]) == {"with"}  # §2.1


def test_normalised_to_the_highest_mean_at_1p04rpm_6mnm(ds, blocks):
    key = (6.0, 1.04)
    assert max(blocks, key=lambda k: blocks[k].mean()) == key
    norm = ds["torque_normalised"].values
    torque = ds["torque"].values
    ref = torque / norm
    assert np.ptp(ref) < 1e-4 * ref.mean()  # one common reference
    assert ref.mean() / 1e3 == pytest.approx(blocks[key].mean(), rel=1e-5)


def test_load_dependence_nearly_linear_with_positive_zero_load(means):
    assert means[0] > 0
    assert np.all(np.diff(means) > 0)
    fit = np.polyval(np.polyfit(MOMENTS, means, 1), MOMENTS)
    assert np.abs(means - fit).max() < 0.04 * means[-1]


def test_no_systematic_speed_dependence(blocks):
    rel = np.array([blocks[m, 1.04].mean() / blocks[m, 0.5].mean() - 1 for m in MOMENTS])
    assert stats.ttest_1samp(rel, 0.0).pvalue > 0.05
    assert np.abs(rel).max() < 0.06
    sweep = [blocks[5.0, s].mean() for s in (0.5, 0.75, 1.04)]  # Fig. 8 at 5 MNm
    assert abs(sweep[-1] / sweep[0] - 1) < 0.05  # Wang's model: +55 % (Fig. 9)


def test_repetitions_scatter_but_means_agree(ds, blocks):
    loaded = [v for (m, _), v in blocks.items() if m > 0]
    cv = np.array([v.std(ddof=1) / v.mean() for v in loaded])
    assert np.median(cv) > 0.04  # relatively high single-measurement scatter (§3.2)
    assert np.all(cv / np.sqrt(20) < 0.03)  # ... while the block means are well determined
    rep = ds["repetition"].values
    torque = ds["torque"].values / 1e3
    moment = np.round(ds["bending_moment"].values / 1e6, 6)
    speed = np.round(ds["velocity"].values * 30.0 / np.pi, 6)
    rel = torque / np.array([blocks[m, s].mean() for m, s in zip(moment, speed, strict=True)])
    # no significant difference between repetitions (one-way ANOVA by repetition index)
    assert stats.f_oneway(*[rel[rep == r] for r in np.unique(rep)]).pvalue > 0.05


def test_rothe_erde_comparison_as_in_the_paper(means):
    re_slope = 2.2 * MU_ROTHE_ERDE * 1e3  # Eq. 15, kN·m per MN·m
    slope = (means[6] - means[0]) / 6.0
    assert re_slope / slope == pytest.approx(1.15, abs=0.03)  # 15 % steeper (§3.2)
    assert 1 - 2 * re_slope / means[2] == pytest.approx(0.35, abs=0.03)  # 35 % at 2 MNm
    assert 1 - 6 * re_slope / means[6] == pytest.approx(0.10, abs=0.03)  # 10 % at 6 MNm


def test_derived_zero_load_to_slope_ratio_and_convexity(means):
    # README §4, by hand: T(6) = 6.9k/0.9 = 23/3 k, T(0) = T(6) - 6k = 5/3 k, T(2) = 2.3k/0.65
    t6 = Fraction(69, 10) / Fraction(9, 10)
    t2 = Fraction(23, 10) / Fraction(65, 100)
    assert (t6, t6 - 6, t2) == (Fraction(23, 3), Fraction(5, 3), Fraction(46, 13))
    assert _generator().derived_targets() == {"T0": Fraction(5, 3), "T2": Fraction(46, 13),
                                              "T6": Fraction(23, 3)}
    slope = (means[6] - means[0]) / 6.0
    assert means[0] / slope == pytest.approx(5 / 3, abs=0.1)
    below_chord = float(t6 - 6 + 2 - t2)  # 0.128 k: T(2) lies below the 0-6 MNm chord
    assert below_chord == pytest.approx(0.1282, abs=1e-4)
    assert (means[0] + 2 * slope - means[2]) / slope == pytest.approx(below_chord, abs=0.1)


def test_absolute_scale_from_catalogue_coefficient(means):
    k = 2.2 * MU_ROTHE_ERDE * 1e3 / 1.15  # 7.652 kN·m per MN·m
    assert k == pytest.approx(7.652, abs=1e-3)
    assert _generator().load_slope_knm_per_mnm() == pytest.approx(k, rel=1e-12)
    assert means[6] == pytest.approx(23 / 3 * k, rel=0.03)  # 58.7 kN·m
    assert means[0] == pytest.approx(5 / 3 * k, rel=0.05)  # 12.8 kN·m


def test_truth_coefficients_physical():
    coef = _generator().truth_coefficients()
    from bayesfric.laws.ball_loads import PITCH_BEARING

    # P1 term as a Palmgren-type sliding coefficient: T = mu_s * (D_M / 2) * P1
    mu_s = coef["c_p1"] * 1e3 / (PITCH_BEARING.pitch_diameter / 2)
    assert 0.001 < mu_s < 0.01
    assert coef["c_s43"] > 0 and coef["seal"] > 0


def test_regeneration_is_bit_identical(tmp_path):
    subprocess.run([sys.executable, str(DATA / "generate.py"), str(tmp_path)], check=True)
    for name in ("pitch_bearing.csv", "pitch_bearing.toml"):
        assert (tmp_path / name).read_bytes() == (DATA / name).read_bytes(), name
