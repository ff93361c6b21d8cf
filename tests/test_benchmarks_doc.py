"""docs/benchmarks.md is what scripts/make_benchmarks_doc.py makes of its fragments.

Text written into docs/benchmarks.md by hand is lost the next time the script runs (it lost the
139 lines of issue 20's production-scene study once); such text lives in a fragment under
docs/bench/ instead.
"""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "scripts" / "make_benchmarks_doc.py"


def test_benchmarks_doc_is_its_fragments():
    done = subprocess.run([sys.executable, str(SCRIPT), "--check"], capture_output=True, text=True, cwd=ROOT)
    assert done.returncode == 0, done.stdout + done.stderr


def test_check_writes_nothing_and_says_what_differs(tmp_path, monkeypatch):
    sys.path.insert(0, str(SCRIPT.parent))
    try:
        import make_benchmarks_doc as mbd
    finally:
        sys.path.remove(str(SCRIPT.parent))
    docs = tmp_path / "docs"
    docs.mkdir()
    (docs / "benchmarks.md").write_text("edited by hand\n")
    monkeypatch.setattr(mbd, "DOCS", docs)
    assert mbd.main(["--check"]) == 1
    assert (docs / "benchmarks.md").read_text() == "edited by hand\n"
    assert mbd.main([]) == 0
    assert (docs / "benchmarks.md").read_text() == mbd.render()

