"""Law family 'thermal' (being written; see the law-library issue)."""
