"""A failed batch job leaves no new empty folder behind: the folders it created for its output
are removed again while empty (docs/batch.md). A folder that was there before, or that holds
anything (another job's output, other files), stays.

Before, ``batch`` created the output's folders (``ensure_folder``) and left them, empty, when the
job then failed (a syntax error in its input, say), as ``simulate`` already did not.
"""

from __future__ import annotations

from pathlib import Path

from batch_stages import groom_stage, write_jobs

from dftl_warp import cli


def test_failed_jobs_leave_no_new_empty_folder_and_keep_the_others(tmp_path, capsys):
    good = groom_stage(tmp_path / "good.usda", strands=2, vertices=4, end=2)
    broken = tmp_path / "broken.usda"
    broken.write_text('#usda 1.0\ndef X "a" {\n')
    (tmp_path / "kept").mkdir()                      # there before, empty
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "notes.txt").write_text("a TD's file")
    jobs = write_jobs(tmp_path / "jobs.toml", [
        {"input": str(broken), "output": "new/deep/a.usdc"},
        {"input": str(broken), "output": "kept/b.usdc"},
        {"input": str(broken), "output": "busy/new/c.usdc"},
        {"input": str(broken), "output": "shared/d.usdc"},
        {"input": str(good), "output": "shared/e.usdc"},
    ], defaults={"end": 2})
    assert cli.main(["batch", str(jobs), "--workers", "1", "-q"]) == 1
    err = capsys.readouterr().err
    assert err.count("dftl-warp: error: ") == 4 and "Traceback" not in err, err
    assert not (tmp_path / "new").exists()
    assert (tmp_path / "kept").is_dir() and list((tmp_path / "kept").iterdir()) == []
    assert sorted(p.name for p in (tmp_path / "busy").iterdir()) == ["notes.txt"]
    assert sorted(p.name for p in (tmp_path / "shared").iterdir()) == ["e.usdc"]
    assert sorted(p.name for p in Path(tmp_path).iterdir()) == ["broken.usda", "busy", "good.usda", "jobs.toml",
                                                               "kept", "shared"]
