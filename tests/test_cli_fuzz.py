"""The README's error promise for every command, fuzzed: broken stages, garbage attribute values
and bad flags end in exit status 2 with exactly one stderr line and no traceback (and no output
file), or in success. ``batch`` reports failed jobs with status 1 and one line per job.

``dftl_warp.cli.main`` runs in-process; ``capfd`` sees the file-descriptor level too (USD's and
Warp's native messages would be extra lines)."""

from __future__ import annotations

import itertools
import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dftl_warp import cli

FUZZ = settings(max_examples=25, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])

VALID = """#usda 1.0
(
    defaultPrim = "World"
    endTimeCode = 3
    metersPerUnit = 1
    startTimeCode = 1
    timeCodesPerSecond = 24
    upAxis = "Y"
)

def Xform "World"
{
    double3 xformOp:translate = (0, 1, 0)
    uniform token[] xformOpOrder = ["xformOp:translate"]

    def BasisCurves "Hair"
    {
        int[] curveVertexCounts = [4, 4]
        custom int dftl:substeps = 2
        custom float dftl:damping = 0.9
        point3f[] points = [(0, 0, 0), (0, -0.1, 0), (0, -0.2, 0), (0, -0.3, 0), (0.1, 0, 0), (0.1, -0.1, 0), (0.1, -0.2, 0), (0.1, -0.3, 0)]
        uniform token type = "linear"
        float[] widths = [0.01] (
            interpolation = "constant"
        )
    }

    def Sphere "Head"
    {
        double radius = 0.05
        double3 xformOp:translate = (0, 0.2, 0)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }
}
"""

#: (text in VALID, replacements) for garbage attribute values; each keeps or breaks the syntax
GARBAGE = {
    "[4, 4]": ["[4, 5]", "[0, 8]", "[-1, 9]", "[]", "[1, 1, 1, 1, 1, 1, 1, 1]", "[8]", "[\"a\"]", "[4.5, 4]"],
    "dftl:substeps = 2": ["dftl:substeps = 0", "dftl:substeps = -3", "dftl:substeps = 99999999999"],
    "dftl:damping = 0.9": ["dftl:damping = nan", "dftl:damping = -1", "dftl:damping = inf", "dftl:damping = 2"],
    "(0, -0.3, 0)": ["(nan, 0, 0)", "(inf, 0, 0)", "(1e30, 0, 0)", "(0, 0)", "(0, -0.3, 0), (0, 1, 0)"],
    '"linear"': ['"cubic"', '"quadratic"', '""'],
    "[0.01]": ["[-1]", "[nan]", "[0.01, 0.02, 0.03]", "[]", "[1e30]"],
    '"constant"': ['"vertex"', '"uniform"', '"bogus"'],
    "timeCodesPerSecond = 24": ["timeCodesPerSecond = 0", "timeCodesPerSecond = -24", "timeCodesPerSecond = nan"],
    "endTimeCode = 3": ["endTimeCode = 0", "endTimeCode = -5", "endTimeCode = nan", "endTimeCode = 2.5"],
    "metersPerUnit = 1": ["metersPerUnit = 0", "metersPerUnit = -1", "metersPerUnit = nan"],
    "radius = 0.05": ["radius = -1", "radius = nan", "radius = inf"],
    "(0, 1, 0)": ["(nan, 0, 0)", "(1e300, 0, 0)"],
    'upAxis = "Y"': ['upAxis = "W"', 'upAxis = ""'],
}


@st.composite
def stages(draw):
    """A truncated or garbled copy of VALID (or VALID itself)."""
    text = VALID
    kind = draw(st.sampled_from(["valid", "truncated", "garbage", "garbage", "bytes"]))
    if kind == "truncated":
        text = text[: draw(st.integers(0, len(text) - 1))]
    elif kind == "garbage":
        for key in draw(st.lists(st.sampled_from(sorted(GARBAGE)), min_size=1, max_size=3, unique=True)):
            text = text.replace(key, draw(st.sampled_from(GARBAGE[key])), 1)
    elif kind == "bytes":
        cut = draw(st.integers(0, len(text)))
        text = text[:cut] + draw(st.text(max_size=20)) + text[cut:]
    return text


def flags(table: dict, max_size=3):
    """Lists of [flag, value] picked from ``table`` (flag -> values; None: a switch)."""
    def pick(name):
        values = table[name]
        return st.just([name]) if values is None else st.sampled_from(values).map(lambda v: [name, v])

    return st.lists(st.sampled_from(sorted(table)).flatmap(pick), max_size=max_size).map(
        lambda parts: list(itertools.chain.from_iterable(parts)))


_counter = itertools.count()


def fresh(tmp_path) -> Path:
    folder = tmp_path / f"case{next(_counter)}"
    folder.mkdir()
    return folder


def check(argv, capfd, outputs=(), allowed=(0, 2)):
    """Run the CLI; the promise: status 2 and one stderr line (and no output), or success."""
    capfd.readouterr()
    try:
        code = cli.main([str(a) for a in argv])
    except SystemExit as exc:  # argparse: a bad flag
        code = exc.code
    _, err = capfd.readouterr()
    assert "Traceback" not in err, (argv, err)
    assert code in allowed, (argv, code, err)
    if code == 2:
        lines = err.strip().splitlines()
        assert len(lines) == 1, (argv, err)
        assert "error" in lines[0], (argv, err)
        for out in outputs:
            assert not Path(out).exists(), (argv, out)
    return code, err


SIMULATE_FLAGS = {
    "--start": ["1", "2", "0", "-4", "x", "2.5"],
    "--end": ["1", "3", "2", "-1", "x", ""],
    "--substeps": ["1", "0", "-2", "x"],
    "--damping": ["0", "1", "0.5", "2", "nan", "-0.1"],
    "--correction": ["prior", "posterior", "bogus"],
    "--solver": ["dftl", "ftl", "pbd", "nope"],
    "--iterations": ["1", "0", "x"],
    "--precision": ["float32", "float64", "float16"],
    "--quality": ["draft", "wrong"],
    "--device": ["cpu", "cuda:99", "", ",", "cpu,", "gpu"],
    "--prim": ["/World", "/Nope", "not a path", ""],
    "--bogus": None,
}


@FUZZ
@given(text=stages(), extra=flags(SIMULATE_FLAGS))
def test_simulate(tmp_path, capfd, text, extra):
    folder = fresh(tmp_path)
    src = folder / "in.usda"
    src.write_text(text)
    out = folder / "out.usdc"
    check(["simulate", src, "-o", out, "--quiet", *extra], capfd, outputs=[out])
    assert not [p for p in os.listdir(folder) if p.startswith(".")]


RENDER_FLAGS = {
    "--frame": ["1", "2", "3", "0", "x", "nan"],
    "--start": ["1", "2", "x"],
    "--end": ["2", "3", "0"],
    "--step": ["1", "0", "-1", "0.5"],
    "--camera": ["auto", "/World", "/Nope", "bad path"],
    "--resolution": ["8x8", "0x8", "8", "axb", "-8x8", "8x8x8"],
    "--spp": ["1", "0", "-1", "x"],
    "--device": ["cpu", "cuda:99", ",", ""],
    "--shading": ["kajiya-kay", "phong"],
    "--turntable": ["2", "0", "-1"],
    "--contact-sheet": None,
    "--fps": ["24", "0", "x"],
}


@FUZZ
@given(text=stages(), extra=flags(RENDER_FLAGS), name=st.sampled_from(
    ["x.png", "f.##.png", "x.gif", "x.txt", "sub/x.png", "x"]))
def test_render(tmp_path, capfd, text, extra, name):
    folder = fresh(tmp_path)
    src = folder / "in.usda"
    src.write_text(text)
    out = folder / name
    base = ["--resolution", "8x8", "--spp", "1"]
    code, _ = check(["render", src, "-o", out, "-q", *base, *extra], capfd, outputs=[out])
    if code == 2:
        assert sorted(os.listdir(folder)) == ["in.usda"], os.listdir(folder)


@FUZZ
@given(text=stages(), extra=flags({"--json": None, "--prim": ["/World", "/Nope", "bad path"], "--bogus": None}))
def test_info(tmp_path, capfd, text, extra):
    folder = fresh(tmp_path)
    src = folder / "in.usda"
    src.write_text(text)
    check(["info", src, *extra], capfd)


JOB_LINES = ['input = "missing.usda"', 'output = "o.usdc"', 'output = "o.txt"', "substeps = -1",
             'substeps = "x"', "dampng = 1", "damping = 2", 'device = 3', "[[job]]", "[defaults]",
             'name = "a"', "end = 3", "start = 9", "= =", '"unterminated']


@FUZZ
@given(lines=st.lists(st.sampled_from(JOB_LINES), max_size=8),
       extra=flags({"--workers": ["1", "0", "x"], "--checkpoint-frames": ["0", "-1"],
                    "--checkpoint-seconds": ["0", "nan", "-1"], "--quiet": None}))
def test_batch(tmp_path, capfd, lines, extra):
    """Jobs whose input is missing fail in the batch process (no worker is started): the batch
    ends in status 1 with one error line per failed job, or 2 with one line for the file."""
    folder = fresh(tmp_path)
    jobs = folder / "jobs.toml"
    jobs.write_text("\n".join(lines) + "\n")
    code, err = check(["batch", jobs, *extra], capfd, outputs=[folder / "o.usdc"], allowed=(0, 1, 2))
    if code == 1:
        assert all(line.startswith(("dftl-warp: error: job", "dftl-warp: [")) for line in err.strip().splitlines()), err


@FUZZ
@given(extra=flags({"--device": ["cuda:99", ",", "nope", "cuda:x"], "--out": ["FILE"], "--bogus": None,
                    "--fast": None}, max_size=3).filter(
    lambda f: any(a in f for a in ("--bogus", "cuda:99", ",", "nope", "cuda:x", "FILE"))))
def test_study(tmp_path, capfd, extra):
    """Only arguments that must be refused (a study that runs takes a while: tests/test_study.py)."""
    folder = fresh(tmp_path)
    (folder / "afile").write_text("x")
    extra = [str(folder / "afile") if a == "FILE" else a for a in extra]
    if "--out" not in extra:
        extra += ["--out", str(folder / "afile")]
    code, _ = check(["study", *extra], capfd)
    assert code == 2


@pytest.fixture(scope="module")
def hair_files(tmp_path_factory):
    from test_importers import write_all

    return {k: Path(v).read_bytes() for k, v in write_all(tmp_path_factory.mktemp("hair")).items()}


IMPORT_FLAGS = {
    "--units": ["m", "cm", "furlongs", "-1", "0"],
    "--up-axis": ["Y", "Z", "X", "W"],
    "--width": ["0.1", "0", "-1", "nan"],
    "--max-strands": ["1", "0", "-1"],
    "--every": ["1", "2", "0"],
    "--segments": ["2", "0", "-3"],
    "--drop-nonfinite": None,
    "--quiet": None,
}


@FUZZ
@given(data=st.data(), extra=flags(IMPORT_FLAGS))
def test_import(tmp_path, capfd, hair_files, data, extra):
    fmt = data.draw(st.sampled_from(sorted(hair_files)))
    blob = hair_files[fmt]
    kind = data.draw(st.sampled_from(["valid", "truncated", "flipped", "random"]))
    if kind == "truncated":
        blob = blob[: data.draw(st.integers(0, len(blob) - 1))]
    elif kind == "flipped":
        i = data.draw(st.integers(0, len(blob) - 1))
        blob = blob[:i] + bytes([blob[i] ^ data.draw(st.integers(1, 255))]) + blob[i + 1:]
    elif kind == "random":
        blob = data.draw(st.binary(max_size=64))
    folder = fresh(tmp_path)
    src = folder / {"hair": "g.hair", "data": "g.data", "ct2hair": "g.bin", "tfx": "g.tfx", "ply": "g.ply"}[fmt]
    src.write_bytes(blob)
    out = folder / "o.usda"
    check(["import", src, "-o", out, *extra], capfd, outputs=[out])
