"""Law family 'hysteresis' (being written; see the law-library issue)."""
