"""A leading ``~`` in any path option means the home folder, as a shell would read it.

The shell expands ``~`` only in a word of its own, so ``--out=~/x``, a quoted ``"~/x"``, a job
launcher's argument list or a batch TOML passed it on literally: ``study --out=~/x`` made a folder
named ``~`` in the current folder. Every path option of every command now goes through one
argparse type (``dftl_warp.output.paths.path_argument``); a batch TOML's paths expand the same way.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from usd_stages import add_curves, chain, new_stage

from dftl_warp import cli

FRONT = Path(__file__).parents[1] / "docs" / "accuracy-h200" / "front.json"


@pytest.fixture
def home(tmp_path, monkeypatch):
    """A fresh home folder, and a current folder beside it (where a literal ``~`` would go)."""
    home = tmp_path / "home"
    home.mkdir()
    here = tmp_path / "here"
    here.mkdir()
    monkeypatch.setenv("HOME", str(home))
    monkeypatch.chdir(here)
    return home


def no_tilde_folder():
    assert not Path("~").exists(), "a folder literally named ~ was made"


def hair(path: Path) -> Path:
    stage = new_stage(path)
    add_curves(stage, "/World/Hair", chain(4, spacing=0.1), [4])
    stage.Save()
    return path


def test_study_out_and_front_from_expand_the_home_folder(home, capsys):
    shutil.copy(FRONT, home / "front.json")
    assert cli.main(["study", "--front-from=~/front.json", "--out=~/x", "--quiet"]) == 0, capsys.readouterr().err
    assert (home / "x" / "front.md").is_file()
    no_tilde_folder()


def test_simulate_info_diff_and_render_read_and_write_under_home(home, capsys):
    hair(home / "in.usda")
    assert cli.main(["simulate", "~/in.usda", "--output=~/shots/out.usdc", "--end", "2", "--device", "cpu", "-q"]) == 0
    assert (home / "shots" / "out.usdc").is_file()
    assert cli.main(["info", "~/shots/out.usdc"]) == 0
    assert cli.main(["diff", "~/shots/out.usdc", "~/shots/out.usdc"]) == 0
    assert cli.main(["render", "~/shots/out.usdc", "--output=~/img/a.png", "--resolution", "8x6", "--spp", "1",
                     "--device", "cpu", "-q"]) == 0
    assert (home / "img" / "a.png").is_file()
    no_tilde_folder()
    capsys.readouterr()


def test_import_expands_its_input_output_and_head(home, capsys):
    (home / "g.ply").write_text("\n".join(
        ["ply", "format ascii 1.0", "element vertex 6", "property float x", "property float y", "property float z",
         "element strand 2", "property int vertex_count", "end_header",
         "0 0 0", "0 -1 0", "0 -2 0", "1 0 0", "1 -1 0", "1 -2 0", "3", "3"]) + "\n")
    (home / "head.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    assert cli.main(["import", "~/g.ply", "--output=~/groom.usda", "--head=~/head.obj", "-q"]) == 0, \
        capsys.readouterr().err
    assert (home / "groom.usda").is_file()
    no_tilde_folder()


def test_batch_expands_the_job_list_and_the_paths_in_it(home, capsys):
    hair(home / "in.usda")
    (home / "jobs.toml").write_text('[defaults]\nend = 2\n\n[[job]]\ninput = "~/in.usda"\noutput = "~/out/a.usdc"\n')
    assert cli.main(["batch", "~/jobs.toml", "--workers", "1", "-q"]) == 0, capsys.readouterr().err
    assert (home / "out" / "a.usdc").is_file()
    assert not (home / "~").exists()
    no_tilde_folder()

