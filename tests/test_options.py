"""The one table of options (dftl_warp/options.py): the CLI, the USD reader, the batch TOML and the
Python API all validate from it; names of higher layers written out in it agree with them."""

import ast
import inspect
from pathlib import Path

import numpy as np
import pytest

from dftl_warp import cli, options
from dftl_warp.errors import UserError
from dftl_warp.options import BY_API, BY_TOML, BY_USD, OPTIONS, OptionError

ROOT = Path(__file__).resolve().parent.parent / "dftl_warp"


def test_solver_choices_are_the_registry():
    from dftl_warp.solvers import SOLVERS

    assert options.SOLVER_NAMES == tuple(SOLVERS)
    assert OPTIONS["solver"].choices == tuple(SOLVERS)


def test_names_of_higher_layers_agree():
    from dftl_warp.core.precision import PRECISIONS
    from dftl_warp.kernels.solvers.ftl import CORRECTIONS
    from dftl_warp.simulation.quality import QUALITY_PRESETS

    assert OPTIONS["correction"].choices == tuple(CORRECTIONS)
    assert OPTIONS["precision"].choices == tuple(PRECISIONS)
    assert OPTIONS["quality"].choices == tuple(QUALITY_PRESETS)


def _features():
    """The features' attribute table and mapping (dftl_warp.features)."""
    import dftl_warp.features as F

    return F


def test_feature_attributes_agree_with_the_features():
    ATTRIBUTES = _features().ATTRIBUTES  # noqa: N806

    assert set(options.FEATURE_ATTRIBUTES) == set(ATTRIBUTES)
    for name, spec in ATTRIBUTES.items():
        assert BY_USD[name].type == spec[0], name
        assert BY_USD[name].scope == spec[1], name


def test_feature_defaults_agree_with_the_features():
    from dftl_warp.features import HairHair, Wind
    from dftl_warp.features.hair_hair import DEFAULT_REPULSION

    feats = _features().features_from_attributes({"dftl:drag": 1.0, "dftl:wind": [1.0, 0.0, 0.0], "dftl:hairHair": True},
                                     [{}], [1], mean_segment=0.1)
    wind = next(f for f in feats if isinstance(f, Wind))
    assert wind.noise_amplitude == OPTIONS["windNoise"].default
    assert wind.noise_scale == OPTIONS["windNoiseScale"].default
    assert wind.noise_frequency == OPTIONS["windNoiseFrequency"].default
    assert wind.seed == OPTIONS["windSeed"].default
    hh = next(f for f in feats if isinstance(f, HairHair))
    assert hh.friction == OPTIONS["hairHairFriction"].default
    # the table's None: the feature's SI default, in stage units (here metres)
    assert OPTIONS["hairHairRepulsion"].default is None
    assert hh.repulsion == DEFAULT_REPULSION
    # None in both: the densest node of the hair at rest, found when the grid is set up
    assert hh.threshold is None and OPTIONS["hairHairThreshold"].default is None
    assert hh.splat_interval == OPTIONS["hairHairSplatInterval"].default


def test_pbd_iterations_default_is_the_table_default():
    from dftl_warp.solvers import PBDSolver

    assert inspect.signature(PBDSolver).parameters["iterations"].default == OPTIONS["iterations"].default


def test_old_default_names_read_the_table():
    from dftl_warp.simulation import settings, simulate

    for name in ("damping", "correction", "substeps"):
        assert getattr(settings, f"DEFAULT_{name.upper()}") == OPTIONS[name].default
        assert getattr(simulate, f"DEFAULT_{name.upper()}") == OPTIONS[name].default
    # the table leaves the solver unset: a prim with widths gets "elastic", one without DEFAULT_SOLVER
    assert OPTIONS["solver"].default is None and settings.DEFAULT_SOLVER == simulate.DEFAULT_SOLVER == "dftl"


def _imports(path: Path) -> set[str]:
    """Absolute names of every module ``path`` imports (inside functions too)."""
    package = ".".join(path.relative_to(ROOT.parent).with_suffix("").parts[:-1])
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(parts + ([base] if base else []))
            found.add(base)
            found.update(f"{base}.{a.name}" for a in node.names)
    return found


def test_options_is_a_foundation_module():
    own = {n for n in _imports(ROOT / "options.py") if n.startswith("dftl_warp")}
    assert own <= {"dftl_warp.errors", "dftl_warp.errors.UserError"}, own


def test_the_usd_reader_imports_only_errors_options_checks_and_usd():
    """The foundation (errors, options, checks: check_lengths) and itself."""
    for path in (ROOT / "usd").glob("*.py"):
        own = {n for n in _imports(path) if n.startswith("dftl_warp")}
        bad = {n for n in own if not (n.startswith(("dftl_warp.errors", "dftl_warp.options", "dftl_warp.checks",
                                                    "dftl_warp.usd")) or n == "dftl_warp")}
        assert not bad, (path.name, bad)


def test_the_writer_uses_the_public_tf_message():
    text = (ROOT / "output" / "usd.py").read_text()
    assert "usd.read import _tf_message" not in text
    from dftl_warp.usd.stage import tf_message

    assert tf_message(RuntimeError("  a\n b ")) == "a b"


# -- the command line --------------------------------------------------------------------------


def _simulate_parser():
    parser = cli.build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    return sub.choices["simulate"]


def test_every_simulate_flag_comes_from_the_table():
    actions = {a.option_strings[-1]: a for a in _simulate_parser()._actions if a.option_strings}
    for flag in ("--output", "--start", "--end", "--substeps", "--damping", "--correction", "--solver",
                 "--iterations", "--precision", "--quality", "--device", "--prim", "--quiet"):
        assert flag in actions, flag
    for o in OPTIONS.values():
        if o.cli is None:
            continue
        a = actions[o.cli]
        assert a.help.replace("%%", "%").startswith(o.help)  # argparse needs a % doubled
        if o.choices and o.name != "solver":
            assert tuple(a.choices) == o.choices
        assert a.default == (o.default if o.name == "device" else None), o.name
    assert actions["--prim"].dest == "prim" and actions["--prim"].metavar == "PATH"


@pytest.mark.parametrize("argv, message", [
    (["--substeps", "0"], "must be >= 1, got 0"),
    (["--substeps", "2.5"], "not an integer: '2.5'"),
    (["--damping", "1.5"], "must be in [0, 1], got 1.5"),
    (["--damping", "nan"], "must be in [0, 1], got nan"),
    (["--damping", "x"], "not a number: 'x'"),
    (["--iterations", "-1"], "must be >= 1, got -1"),
    (["--correction", "sideways"], "invalid choice"),
])
def test_bad_flags_are_refused_by_argparse(argv, message, capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(["simulate", "in.usda", "-o", "o.usdc", *argv])
    assert exc.value.code == 2
    assert message in capsys.readouterr().err


# -- the batch TOML ----------------------------------------------------------------------------


def test_every_toml_key_is_checked_by_the_table():
    from dftl_warp.batch.jobs import _simulate_options

    validators = _simulate_options()
    assert set(validators) == set(BY_TOML)
    assert validators["damping"](0.5, "damping") == 0.5
    assert validators["prim"]("/World", "prim") == ["/World"]
    assert validators["device"]("cuda:0, cuda:1", "device") == "cuda:0,cuda:1"
    with pytest.raises(ValueError, match=r"iterations must be >= 1, got 0"):
        validators["iterations"](0, "iterations")
    with pytest.raises(ValueError, match=r"quality must be one of draft, production, reference"):
        validators["quality"]("best", "quality")


def test_unknown_toml_key_suggests_the_table_key(tmp_path):
    from dftl_warp.batch.jobs import load_jobs

    (tmp_path / "jobs.toml").write_text('[[job]]\ninput = "a.usda"\noutput = "a.usdc"\nitterations = 3\n')
    job = load_jobs(tmp_path / "jobs.toml")[0]
    assert "unknown option 'itterations' (did you mean 'iterations'?)" in job.error


# -- the Python API ----------------------------------------------------------------------------


@pytest.mark.parametrize("kwargs, message", [
    ({"substeps": 0}, "substeps must be >= 1, got 0"),
    ({"substeps": 2.5}, "substeps must be an integer, got 2.5"),
    ({"damping": float("nan")}, "damping must be in [0, 1], got nan"),
    ({"damping": "high"}, "damping must be a number in [0, 1]"),
    ({"solver": "magic"}, "solver must be one of dftl, ftl, pbd, reference"),
    ({"correction": "later"}, "correction must be one of prior, posterior"),
    ({"precision": "float16"}, "precision must be one of float32, float64"),
    ({"device": "gpu0"}, "device must be cpu, cuda:N"),
    ({"prims": ["World"]}, "prims must be a prim path"),
    ({"iterations": True}, "iterations must be an integer"),
    ({"start": "one"}, "start must be an integer"),
    ({"substeps": 10**9}, "substeps must be at most 16384, got 1000000000"),
    ({"substeps": 10**20}, "substeps must be at most 16384"),
    ({"preroll": 1e9}, "preroll must be at most 60, got 1000000000.0"),
    ({"iterations": 5000}, "iterations must be at most 1024"),
])
def test_simulation_options_check_every_field(kwargs, message):
    from dftl_warp.simulation.settings import SimulationOptions

    with pytest.raises(OptionError) as exc:
        SimulationOptions(**kwargs)
    assert message in str(exc.value)
    assert isinstance(exc.value, ValueError) and isinstance(exc.value, UserError)


def test_simulation_options_normalise_and_default():
    from dftl_warp.simulation.settings import SimulationOptions

    o = SimulationOptions(substeps=np.int64(3), damping=1, prims="/World", precision=None, device="cpu, cpu")
    assert o.substeps == 3 and type(o.substeps) is int
    assert o.damping == 1.0 and type(o.damping) is float
    assert o.prims == ["/World"] and o.precision == OPTIONS["precision"].default and o.device == "cpu,cpu"
    assert set(BY_API) >= {f for f in SimulationOptions.__dataclass_fields__}


def test_simulate_usd_checks_its_options_before_reading(tmp_path):
    from dftl_warp.simulation.simulate import simulate_usd

    with pytest.raises(ValueError, match="damping must be in"):
        simulate_usd(tmp_path / "missing.usda", tmp_path / "o.usdc", damping=2.0)
    assert not (tmp_path / "o.usdc").exists()


def test_a_registered_solver_is_accepted_by_every_front_end():
    from dftl_warp.simulation.settings import SimulationOptions
    from dftl_warp.solvers import SOLVERS, DFTLSolver, register

    saved = OPTIONS["solver"].choices

    class Toy(DFTLSolver):
        name = "toy"

    try:
        register(Toy)
        assert "toy" in OPTIONS["solver"].choices and "toy" in BY_USD["dftl:solver"].choices
        assert SimulationOptions(solver="toy").solver == "toy"
        assert options.check_toml("solver", "toy") == "toy"
    finally:
        SOLVERS.pop("toy", None)
        object.__setattr__(OPTIONS["solver"], "choices", saved)


def test_the_table_is_complete():
    for o in OPTIONS.values():
        assert o.help, o.name
        assert o.usd is None or (o.usd.startswith("dftl:") and o.scope in options.SCOPES), o.name
        if o.default is not None and o.type in (int, float, bool, str):
            assert o.check(o.default) == o.default, o.name


def test_simulate_usd_names_a_misspelt_keyword(tmp_path):
    """A misspelt keyword of simulate_usd gets the did-you-mean the CLI and the TOML give (it was
    Python's bare TypeError from the options dataclass); nothing is written."""
    import dftl_warp as dw

    with pytest.raises(TypeError, match=r"simulate_usd: unknown keyword 'substep' \(did you mean 'substeps'\?\)"):
        dw.simulate_usd(tmp_path / "missing.usda", tmp_path / "out.usdc", substep=4)
    assert not (tmp_path / "out.usdc").exists()


def test_a_bad_check_through_the_api_names_the_keyword_not_the_flag(tmp_path):
    """simulate_usd(check=...) says `check`, the keyword it was given (it said `--check`)."""
    import dftl_warp as dw
    from dftl_warp.errors import UserError

    with pytest.raises(UserError, match=r"^check 'strech<1e-3': each gate is METRIC<LIMIT"):
        dw.simulate_usd(tmp_path / "missing.usda", tmp_path / "out.usdc", check="strech<1e-3")


def test_substeps_preroll_and_iterations_have_a_limit_in_every_front_end():
    """--substeps 10**9 or --preroll 1e9 had no limit (days of running); the table's ``limit`` is
    refused by the CLI, the API, the batch TOML and the USD reader alike, and --help shows it."""
    from dftl_warp.batch.jobs import _simulate_options
    from dftl_warp.options import MAX_ITERATIONS, MAX_PREROLL, MAX_SUBSTEPS, BadValue, usd_message

    assert (MAX_SUBSTEPS, MAX_ITERATIONS, MAX_PREROLL) == (16384, 1024, 60.0)
    assert OPTIONS["substeps"].check(MAX_SUBSTEPS) == MAX_SUBSTEPS and OPTIONS["preroll"].check(60) == 60.0
    with pytest.raises(ValueError, match=r"substeps must be at most 16384, got 16385"):
        _simulate_options()["substeps"](16385, "substeps")
    with pytest.raises(ValueError, match=r"preroll must be at most 60, got 61"):
        _simulate_options()["preroll"](61, "preroll")
    with pytest.raises(BadValue) as exc:
        OPTIONS["substeps"].check(100000)
    assert usd_message(exc.value, "in.usda: /World/Hair") == "in.usda: /World/Hair: dftl:substeps = 100000: must be at most 16384"
    helps = {a.option_strings[-1]: a.help for a in _simulate_parser()._actions if a.option_strings}
    assert "solver steps per frame, >= 1, at most 16384" in helps["--substeps"]
    assert ">= 0, at most 60 (s)" in helps["--preroll"] and ">= 1, at most 1024" in helps["--iterations"]
