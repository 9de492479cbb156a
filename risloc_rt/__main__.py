"""``python -m risloc_rt`` is ``risloc``."""

import sys

from .cli import main

sys.exit(main())
