"""Monte Carlo studies (``risloc study sweep``) and floor maps (``risloc study map``), floor 5.

``StudySpec`` says what to vary; ``run_study`` runs it resumably (an append-only run log,
``runs.parquet``, ``summary.json``, a figure in the paper's style) on local processes or a Dask
cluster. See ``docs/studies.md``.
"""

from .engine import StudyError
from .params import PARAMETERS
from .spec import StudySpec, load_study_file, spec_from_options
from .store import StudyFolderError, read_runs_table
from .sweep import StudyResult, run_study

__all__ = ["PARAMETERS", "StudyError", "StudyFolderError", "StudyResult", "StudySpec", "load_study_file",
           "read_runs_table", "run_study", "spec_from_options"]
