"""The version of risloc-rt (one definition, importable from every floor)."""

__version__ = "0.1.0"
