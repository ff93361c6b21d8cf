#!/usr/bin/env python3
"""Regenerate docs/accuracy.md and docs/accuracy/ (the accuracy study).

    python scripts/study.py                                    # CPU, full study, into docs/
    python scripts/study.py --device cuda:0 --out docs/accuracy-h200 --docs docs/accuracy-h200/accuracy-h200.md
    python scripts/study.py --fast --out /tmp/study            # the CI subset

Arguments are those of ``dftl-warp study``; here ``--out`` defaults to docs/accuracy and
``--docs`` to docs/accuracy.md when --out is not given.
"""

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

from dftl_warp.cli import main  # noqa: E402

if __name__ == "__main__":
    argv = sys.argv[1:]
    if "--out" not in argv:
        argv += ["--out", str(ROOT / "docs" / "accuracy")]
        if "--docs" not in argv:
            argv += ["--docs", str(ROOT / "docs" / "accuracy.md")]
    sys.exit(main(["study", *argv]))
