"""The package version (what `prs3-post --version` and every program header say)."""

__version__ = "0.1.0"
