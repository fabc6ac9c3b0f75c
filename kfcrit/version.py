"""The package version (the bottom layer: imported by every layer that records provenance)."""
__version__ = "0.1.0"
