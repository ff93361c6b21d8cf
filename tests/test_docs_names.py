"""Names the docs use exist in the package."""

from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_every_feature_the_docs_call_exists():
    """Each ``F.Name(`` written in README.md or docs/*.md is a name of ``dftl_warp.features``: the
    features example called the retired ``F.ShapeRetention``, and the shape table's ``Ellipsoid``
    was not in ``F``."""
    import re

    from dftl_warp import features as F

    texts = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    called = {(p.name, name) for p in texts for name in re.findall(r"\bF\.([A-Za-z_]\w*)\(", p.read_text())}
    missing = sorted((f, n) for f, n in called if not hasattr(F, n))
    assert not missing, missing
    assert "Ellipsoid" in F.__all__
