"""Monte Carlo studies (``risloc study sweep``), floor maps (``risloc study map``) and the speed
study (``risloc speed``), floor 5.

``StudySpec`` says what to vary; ``run_study`` runs it resumably (an append-only run log,
``runs.parquet``, ``summary.json``, a figure in the paper's style) on local processes or a Dask
cluster; :mod:`risloc_rt.studies.floor_map` runs a hall's floor grid on the same engine (its own
point preparer), :mod:`risloc_rt.studies.speed` times estimators and trace settings. See
``docs/studies.md`` (the module layout is at its end).
"""

from .engine import StudyError
from .params import PARAMETERS
from .spec import StudySpec, load_study_file, spec_from_options
from .store import StudyFolderError, read_runs_table
from .sweep import StudyResult, run_study

__all__ = ["PARAMETERS", "StudyError", "StudyFolderError", "StudyResult", "StudySpec", "load_study_file",
           "read_runs_table", "run_study", "spec_from_options"]
