"""Registers the tests' written-out grid search, ``grid_oracle.py`` next to this file, as the module
``grid_oracle`` (the tests run with ``--import-mode=importlib``: this folder is not on ``sys.path``)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

if "grid_oracle" not in sys.modules:
    _spec = importlib.util.spec_from_file_location("grid_oracle", Path(__file__).with_name("grid_oracle.py"))
    sys.modules["grid_oracle"] = _module = importlib.util.module_from_spec(_spec)
    _spec.loader.exec_module(_module)
