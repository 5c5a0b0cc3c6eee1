"""The package version (a base module: importing it runs nothing else of bayesfric)."""

__version__ = "0.1.0"
