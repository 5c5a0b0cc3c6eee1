"""Law family 'bearing' (being written; see the law-library issue)."""
