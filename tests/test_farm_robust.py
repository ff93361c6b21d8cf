"""What a render-farm wrangler hits: outputs behind symlinks, folders that are files, runs killed
with SIGKILL (their leftovers), and the job file's one-line refusals."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from batch_stages import groom_stage, hidden_files, write_jobs
from dftl_warp.batch.checkpoint import run_job
from dftl_warp.batch.jobs import Job, load_jobs


@pytest.fixture(scope="module")
def stage(tmp_path_factory):
    return groom_stage(tmp_path_factory.mktemp("in") / "groom.usda", strands=8, vertices=6, end=4)


def test_two_jobs_writing_one_file_through_a_symlinked_folder_are_refused(tmp_path, stage):
    """``out/a.usdc`` and ``link/a.usdc`` with ``link -> out`` are one file: the second job is
    refused at load time (it would overwrite the first's output, and each rerun would redo both)."""
    (tmp_path / "out").mkdir()
    (tmp_path / "link").symlink_to("out")
    jobs = load_jobs(write_jobs(tmp_path / "jobs.toml", [
        {"input": str(stage), "output": "out/a.usdc"},
        {"input": str(stage), "output": "link/a.usdc"},
    ]))
    assert jobs[0].error is None
    assert jobs[1].error is not None and "link/a.usdc is also the output of job 1" in jobs[1].error


def test_an_output_folder_that_is_a_file_fails_the_job_in_one_line(tmp_path, stage):
    """``output = "afile/x.usdc"`` where ``afile`` is a file: the job fails with the one line
    simulate gives, not an internal error."""
    (tmp_path / "afile").write_text("")
    job = Job(index=1, name="x", input=str(stage), output=str(tmp_path / "afile" / "x.usdc"), options={"end": 2})
    result = run_job(job, "cpu")
    assert result.status == "failed"
    assert "internal error" not in result.error, result.error
    assert "cannot write" in result.error and "afile" in result.error, result.error
