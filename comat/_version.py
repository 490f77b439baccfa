"""The package version (one place: the root package re-exports it, lower floors read it here)."""

__version__ = "0.1.0"
