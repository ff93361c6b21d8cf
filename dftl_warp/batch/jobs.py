"""The job list of ``dftl-warp batch``: a TOML file of ``[[job]]`` tables (``docs/batch.md``).

Each job names an ``input`` stage and an ``output`` layer (paths relative to the TOML file's
folder) and may set the ``dftl-warp simulate`` options by their long names (the options table's
entries with a TOML key: ``start``, ``end``, ``substeps``, ``damping``, ``correction``, ``solver``,
``iterations``, ``precision``, ``arithmetic``, ``quality``, ``device``, ``prim``, ``preroll`` and the
output options ``frame_step``, ``no_velocities``, ``check``, ``clips``, ``no_clips``; not
:data:`SIMULATE_ONLY`), plus a display ``name``. An optional ``[defaults]`` table gives options shared by every job.

A file that cannot be read or parsed is an error of the whole batch; a job with an unknown option
or a bad value is refused alone (:attr:`Job.error`) so that the others still run.
"""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass, field
from pathlib import Path

from ..options import BY_TOML, DEVICE_PATTERN as _DEVICE_PATTERN, GUIDE_OPTIONS, OPTIONS, check_toml, did_you_mean
from ..errors import UserError
from ..output.paths import user_path

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

#: keys a job table may hold besides the simulate options
JOB_KEYS = ("input", "output", "name")
#: ``device`` values (the options table's pattern)
DEVICE_PATTERN = _DEVICE_PATTERN
#: ``simulate`` options a job does not take (docs/batch.md): the options table gives them no
#: TOML key, and a resumed job could not continue them exactly (``--tolerance``'s substep
#: controller is not in the checkpoint; guides change what the output holds)
SIMULATE_ONLY = ("tolerance", *GUIDE_OPTIONS)


def _validator(key):
    def check(value, name):
        if key == "check" and isinstance(value, str):
            _check_gates(value)
        return check_toml(key, value)

    return check


def _check_gates(text: str) -> None:
    """A bad ``check`` in the gates' words, as ``simulate --check`` and the API give them, naming
    the key ``check`` instead of the flag; raises ValueError."""
    from ..output.qc import parse_gates

    try:
        parse_gates(text, name="check")
    except UserError as exc:
        raise ValueError(str(exc)) from None


def _simulate_options():
    """Option name -> validator, matching the long options of ``dftl-warp simulate``: the options
    table's entries with a TOML key (:mod:`dftl_warp.options`)."""
    return {key: _validator(key) for key in BY_TOML}


@dataclass
class Job:
    """One simulation of a batch. ``options`` are :class:`~dftl_warp.simulation.simulate.SimulationOptions`
    fields (``prim`` becomes ``prims``); ``device`` is None when the scheduler picks it."""

    #: 1-based position in the file
    index: int
    name: str
    input: str
    output: str
    options: dict = field(default_factory=dict)
    device: str | None = None
    #: why the job cannot run (bad option or value), or None
    error: str | None = None

    def as_dict(self) -> dict:
        return {k: getattr(self, k) for k in ("index", "name", "input", "output", "options", "device", "error")}

    @classmethod
    def from_dict(cls, data: dict) -> Job:
        return cls(**data)


def _unknown(name: str, known) -> str:
    return f"unknown option {name!r}" + did_you_mean(name, known)


def _check_options(table: dict, where: str, allowed_extra=()) -> dict:
    """Validated simulate options of a TOML table; raises ValueError on the first problem."""
    validators = _simulate_options()
    options = {}
    for key, value in table.items():
        if key in allowed_extra:
            continue
        if key in SIMULATE_ONLY:
            raise ValueError(f"option {key!r} ({OPTIONS[key].cli}) is not available in batch jobs: "
                             f"run that input with dftl-warp simulate (docs/batch.md lists the options jobs take)")
        if key not in validators:
            raise ValueError(_unknown(key, list(validators) + list(allowed_extra)))
        options[key] = validators[key](value, key)
    return options


def load_jobs(path) -> list[Job]:
    """Jobs of the TOML file ``path``. Problems with the file itself raise UserError; problems
    with one job are recorded in its :attr:`Job.error`."""
    path = Path(os.fspath(path))
    try:
        with open(path, "rb") as f:
            data = tomllib.load(f)
    except FileNotFoundError:
        raise UserError(f"{path}: no such file") from None
    except OSError as exc:
        raise UserError(f"{path}: cannot read: {exc.strerror or exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise UserError(f"{path}: not valid TOML: {exc}") from None
    except UnicodeDecodeError as exc:
        raise UserError(f"{path}: not valid TOML: {exc}") from None
    for key in data:
        if key not in ("job", "defaults"):
            raise UserError(f"{path}: unknown top-level key {key!r}; expected [[job]] tables and an optional [defaults]")
    tables = data.get("job", [])
    if not isinstance(tables, list) or not all(isinstance(t, dict) for t in tables):
        raise UserError(f"{path}: 'job' must be an array of tables ([[job]])")
    if not tables:
        raise UserError(f"{path}: no [[job]] tables")
    defaults = data.get("defaults", {})
    if not isinstance(defaults, dict):
        raise UserError(f"{path}: 'defaults' must be a table ([defaults])")
    try:
        defaults = _check_options(defaults, "defaults")
    except ValueError as exc:
        raise UserError(f"{path}: [defaults]: {exc}") from None

    folder = path.parent
    jobs, outputs, clip_folders = [], {}, {}
    for k, table in enumerate(tables, start=1):
        job = _make_job(k, table, defaults, folder)
        if job.error is None:
            key = os.path.normcase(os.path.realpath(job.output))   # one file, however the path reaches it
            # shot.usdc and shot.usd write their value clips (asked for or automatic) into one shot_clips/
            clips = _clips_folder_of(job)
            if key in outputs:
                job.error = f"output {table['output']} is also the output of job {outputs[key]}"
            elif clips is not None and clips in clip_folders:
                job.error = (f"output {table['output']} would write its value clips into {Path(clips).name}/, "
                             f"as the output of job {clip_folders[clips]} does: give it another name")
            else:
                outputs[key] = k
                if clips is not None:
                    clip_folders[clips] = k
        jobs.append(job)
    _check_inputs_survive(jobs, tables)
    for job in jobs:
        if job.error is not None:
            job.error = f"{path}: {job.error}"
    return jobs


def _clips_folder_of(job: Job) -> str | None:
    """The value-clips folder a job's output may fill (a crate output without ``no_clips``), normcased."""
    from ..output.clips import clips_folder

    output = Path(job.output)
    if output.suffix.lower() not in (".usdc", ".usd") or job.options.get("no_clips"):
        return None
    return os.path.normcase(os.path.realpath(clips_folder(output)))


def _check_inputs_survive(jobs: list, tables: list) -> None:
    """A job whose output is another job's input, or a layer or asset that input uses, fails: run
    in either order, it would overwrite the groom the other job reads (simulate checks a job's
    own input when it runs)."""
    from ..output.paths import input_files

    valid = [j for j in jobs if j.error is None]
    if len(valid) < 2:
        return
    used = {j.index: input_files(j.input) for j in valid}
    for job in valid:
        target = os.path.realpath(job.output)
        for other in valid:
            if other is job or target not in used[other.index]:
                continue
            whose = f"job {other.index} ({other.name})"
            what = (f"the input of {whose}" if target == os.path.realpath(other.input)
                    else f"a layer the input of {whose} uses")
            job.error = f"output {tables[job.index - 1]['output']} would overwrite {what}"
            break


def _make_job(k: int, table: dict, defaults: dict, folder: Path) -> Job:
    from ..output import output_extensions

    raw_name = table.get("name")
    output = table.get("output")
    # a blank name or output (output = "  ") named the job "  " in every line about it
    name = raw_name.strip() if isinstance(raw_name, str) and raw_name.strip() else (
        Path(output.strip()).stem if isinstance(output, str) and output.strip() else f"job{k}")
    job = Job(index=k, name=name, input=str(table.get("input", "")), output=str(output or ""))
    try:
        for key in ("input", "output"):
            value = table.get(key)
            if value is None:
                raise ValueError(f"missing {key!r}")
            if not isinstance(value, str):
                raise ValueError(f"{key} must be a path string, got {value!r}")
            if not value.strip():
                raise ValueError(f"{key} = {value!r} is an empty path: give the "
                                 f"{'stage to simulate' if key == 'input' else 'layer to write'}")
        if raw_name is not None and not isinstance(raw_name, str):
            raise ValueError(f"name must be a string, got {raw_name!r}")
        options = {**defaults, **_check_options(table, f"job {k}", allowed_extra=JOB_KEYS)}
        job.input = os.path.abspath(folder / user_path(table["input"]))   # "~/x": the home folder's, as on the
        job.output = os.path.abspath(folder / user_path(table["output"]))  # command line (output.paths)
        if Path(job.output).suffix.lower() not in output_extensions():
            raise ValueError(f"output {table['output']} must end in {', '.join(output_extensions())}")
        if os.path.normcase(job.output) == os.path.normcase(job.input):
            raise ValueError("the output would overwrite the input")
        if options.get("no_clips") and options.get("clips") is not None:   # as simulate --clips --no-clips
            raise ValueError("clips and no_clips contradict each other: keep one")
        start, end = options.get("start"), options.get("end")
        if start is not None and end is not None and end < start:
            raise ValueError(f"frame range {start}..{end} is empty (end before start)")
        if "quality" in options:  # a preset fills the options the job and [defaults] leave unset
            from ..simulation.quality import preset_settings

            for key, value in preset_settings(options["quality"]).items():
                options.setdefault(key, value)
        job.device = options.pop("device", None)
        if "prim" in options:
            options["prims"] = options.pop("prim")
        job.options = options
    except ValueError as exc:
        job.error = str(exc)
    return job
