"""Messages of a run with --guides name the input's strand, not the guide's index.

With ``--guides N`` (curves output) the picked guides are simulated as a prim under the dense prim's
own path, so a message naming 'strand 2' of /World/Hair meant the third guide -- strand 5 of the input
there. Now the energy warning and the clean start's line name the input strand; with ``--guides-output
binding`` the guides are a prim of the output (<prim>_guides) and its strands are named as they are
written there.
"""

from __future__ import annotations

import numpy as np
from usd_stages import add_curves, chain, new_stage

from dftl_warp import cli
from dftl_warp.features.clean_start import strand_name


def test_strand_name_maps_guides_to_their_input_strands():
    prims = [("/A", 3, None), ("/B", 2, np.array([7, 9]))]
    assert strand_name(prims, 1) == "/A strand 1"
    assert strand_name(prims, 4) == "/B strand 9"
    assert strand_name([("/B", 2, np.array([7, 9]))], 0, path=False) == "strand 7"
    assert strand_name([("/A", 3)], 2, path=False) == "strand 2"


def test_energy_warning_names_the_input_strand_of_a_guide(tmp_path, capsys):
    path = tmp_path / "in.usda"
    stage = new_stage(path, start=1, end=8)
    counts = [8, 8, 8, 8, 8, 64]   # DFTL with s = 0 at 40 substeps pumps energy in; the long chain most
    add_curves(stage, "/World/Hair", np.concatenate([chain(n, 0.005, origin=(0, 0, 0.01 * k))
                                                     for k, n in enumerate(counts)]), counts)
    stage.Save()
    named = {}
    for output in ("curves", "binding"):
        assert cli.main(["simulate", str(path), "-o", str(tmp_path / f"{output}.usdc"), "--solver", "dftl",
                         "--damping", "0", "--substeps", "40", "--guides", "3", "--guides-output", output,
                         "-q"]) == 0
        lines = [line for line in capsys.readouterr().err.splitlines() if "energy grew" in line]
        assert len(lines) == 1, lines
        named[output] = lines[0].split("float32: ")[1].split(" (and")[0]
    # the guides are input strands 0, 2 and 5 (kmeans); the 64-vertex chain is the worst
    assert named == {"curves": "strand 5", "binding": "strand 2"}, named
