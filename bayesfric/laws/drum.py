"""Law family 'drum' (being written; see the law-library issue)."""
