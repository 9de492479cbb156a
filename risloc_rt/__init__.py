"""risloc-rt: RIS-enabled self-localization of an FMCW radar, simulated and measured."""

__version__ = "0.1.0"
