"""Model comparison: PSIS-LOO, cross-validation with refits (random, grouped, blocked along the
operating envelope), log evidence from two estimators, weights and averaging, checks, recovery."""
