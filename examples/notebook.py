"""Example (a): fit -> compare -> size on a built-in data set, from Python (each block a notebook cell).

    python examples/notebook.py [--quick]

Fits two laws of robot joint friction (Stäubli RX90 joint 1, measured to 4 rad/s) with NUTS,
ranks them by PSIS-LOO with stacking weights, and asks the better one what torque the drive
must deliver at 6 rad/s, beyond the tested speeds, against a 40 N*m drive. ``--quick`` (CI,
tests/test_example_notebook.py) samples less: a smoke test, not an answer to act on.
"""

import sys

import bayesfric

settings = {"draws": 300, "tune": 300, "chains": 2} if "--quick" in sys.argv else {}  # {}: 4 x 1000 draws

# Data: a built-in data set (`bayesfric data list`), SI units, provenance in its attrs.
data = bayesfric.load_data("robot_joint")
print(f"{data.attrs['name']}: {data.sizes['obs']} points, {data.attrs['provenance']}")

# Fit two laws; relative (proportional) noise, as the robot_joint study uses.
laws = ["stribeck", "joint_tribological"]
fits = {law: bayesfric.fit(law, data, noise="proportional", **settings) for law in laws}

# Compare: PSIS-LOO (high-k points refitted exactly) and stacking weights.
table = bayesfric.compare_laws(fits, data)
print(table[["elpd_loo", "se", "elpd_diff", "weight", "reliable"]].round(3).to_string())
reliable = table.index[table.reliable]  # fits that passed the diagnostics gate, best first
if not len(reliable):  # e.g. --quick's short chains: say so, and go on only to show the API
    print("NO fit passed the diagnostics gate: the answer below is not one to act on")
best = reliable[0] if len(reliable) else table.index[0]

# Size: the best law at 6 rad/s (beyond the tested 4 rad/s), 99 % of |T|, against a 40 N*m drive.
result = bayesfric.size(fits[best], at={"velocity": (6, "rad/s")}, capacity=(40, "N*m"), confidence=0.99)
answer = result.dataset.sel(law=best, point=0)  # one Dataset: law × point (× quantile), SI units
p = answer["p_exceed_text"].item()  # "0.012 ± 0.003", or the rule-of-three bound where no draw exceeds
print(f"{best}: required {float(answer['required']):.1f} N*m at 6 rad/s (99 % of |T|); P(|T| > 40 N*m) = {p}")
print(f"  99.9 % of |T|: {float(result.q(0.999).sel(law=best, point=0)):.1f} N*m (any level, from the kept draws)")
if warnings := str(answer["warnings"].item()):
    print("warnings:", warnings)
