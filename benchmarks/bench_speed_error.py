"""Speed against error of every estimator and trace setting in one run: ``risloc speed``.

A thin wrapper so the study sits beside the other benchmarks; the arguments are those of
``risloc speed`` (the study: ``risloc_rt/studies/speed.py``), e.g.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_speed_error.py --realizations 3 --full 1 \\
        --json speed.json --plot docs/speed-error.png
"""

from __future__ import annotations

import sys

from risloc_rt.cli import main

if __name__ == "__main__":
    sys.exit(main(["speed", *sys.argv[1:]]))
