"""The Python API's input audit (a crash, values that do not fit float32, a State of another
model's strands, short writes, coerced options, constructors without type checks, options dropped
without a word): each is refused, or warned about, naming the argument. CPU, tiny models."""

import warnings

import numpy as np
import pytest

import dftl_warp as dw
from dftl_warp import features as F
from dftl_warp.solvers import DFTLSolver, PBDSolver, ReferenceSolver

ELASTIC = ("dftl", "ftl", "pbd", "reference", "rattle", "elastic")


def _chain(n=5, x=0.0, seg=0.01):
    return np.c_[x + np.arange(n) * seg, np.zeros(n), np.zeros(n)]


def _two(n=5):
    return np.concatenate([_chain(n), _chain(n, x=0.5)]), [n, n]


@pytest.fixture(scope="module")
def m32():
    return dw.Model.from_strands(*_two(), device="cpu")


@pytest.fixture(scope="module")
def m64():
    return dw.Model.from_strands(*_two(), device="cpu", precision="float64")


# -- 1. a solver's model is fixed -------------------------------------------------------------------


@pytest.mark.parametrize("name", ELASTIC)
def test_a_solvers_model_cannot_be_swapped(m32, m64, name):
    """``solver.model = other`` left the arrays cached for the first model: reference and rattle
    segfaulted, elastic hung."""
    model = m64 if name == "reference" else m32
    solver = dw.make_solver(model, name)
    other = dw.Model.from_strands(_chain(7), [7], device="cpu", precision=model.precision)
    with pytest.raises(AttributeError, match="a solver's model is fixed at construction: make a new solver"):
        solver.model = other
    assert solver.model is model


# -- 2. values that do not fit float32 ---------------------------------------------------------------


def test_gravity_beyond_float32_is_refused(m32, m64):
    with pytest.raises(ValueError, match=r"gravity\[1\] = -1e\+39 does not fit float32"):
        dw.make_solver(m32, "dftl", gravity=(0, -1e39, 0))
    with pytest.raises(ValueError, match=r"gravity\[1\] = -1e\+30 is too large: its square does not fit float32"):
        dw.make_solver(m32, "pbd", gravity=(0, -1e30, 0))
    dw.make_solver(m64, "dftl", gravity=(0, -1e39, 0))   # float64 holds it


def test_root_targets_beyond_float32_are_refused(m32):
    control = m32.control()
    with pytest.raises(ValueError, match=r"root targets\[0\] = \(1e\+39, 0, 0\) does not fit float32"):
        control.set_root_targets(np.array([[1e39, 0, 0], [0.5, 0, 0]]))


def test_points_and_origin_beyond_float32_are_refused():
    points, counts = _two()
    with pytest.raises(ValueError, match=r"points\[1\] = \(1e\+39, 0, 0\) does not fit float32"):
        dw.Model.from_strands(points * 1e41, counts)
    # representable, but squared lengths overflow: pbd gave NaN, rattle and dftl collapsed
    with pytest.raises(ValueError, match=r"points\[1\] = \(1e\+28, 0, 0\) is too large: its square"):
        dw.Model.from_strands(points * 1e30, counts)
    with pytest.raises(ValueError, match=r"origin = \(1e\+30, 0, 0\) is too large"):
        dw.Model.from_strands(points, counts, origin=(1e30, 0, 0))
    dw.Model.from_strands(points * 1e30, counts, precision="float64")


def test_simulate_strands_roots_beyond_float32_are_refused():
    points, counts = _two()
    with pytest.raises(ValueError, match=r"roots \(flattened rows\)\[0\] = \(1e\+39, 1e\+39, 1e\+39\) does not fit"):
        dw.simulate_strands(points, counts, steps=2, dt=0.01, roots=np.full((3, 2, 3), 1e39))


def test_collider_sizes_and_mesh_points_beyond_float32_are_refused():
    points, counts = _two()
    with pytest.raises(ValueError, match=r"collider 0 \(.*\) size = \(1e\+39, 0, 0\) does not fit float32"):
        dw.Model.from_strands(points, counts, widths=1e-4, features=[F.Colliders([F.Sphere(radius=1e39)])])
    mesh = F.TriangleMesh(points=np.eye(3) - 1, indices=[0, 1, 2])
    model = dw.Model.from_strands(points, counts, widths=1e-4, features=[F.Colliders([mesh])])
    with pytest.raises(ValueError, match=r"mesh collider 0 points\[0\] = \(0, -1e\+39, -1e\+39\) does not fit"):
        model.control().features.set_mesh_points(0, (np.eye(3) - 1) * 1e39)


# -- 3. a State of another model with as many slots ---------------------------------------------------


def test_a_state_of_other_strands_in_as_many_slots_is_refused():
    a = dw.Model.from_strands(np.concatenate([_chain(5), _chain(5, x=0.5)]), [5, 5], device="cpu")
    b = dw.Model.from_strands(np.concatenate([_chain(3), _chain(7, x=0.5)]), [3, 7], device="cpu")
    solver = dw.make_solver(b, "dftl")
    state = dw.make_solver(a, "dftl").state()
    with pytest.raises(ValueError, match="state was made by another model .* make States with this solver's state"):
        solver.advance(state, b.control(), 0.01, 2)
    with pytest.raises(ValueError, match="state_in was made by another model"):
        solver.step(state.clone(), state, b.control(), 0.01)
    # a model rebuilt from the same strands shares its States
    again = dw.Model.from_strands(np.concatenate([_chain(5), _chain(5, x=0.5)]), [5, 5], device="cpu")
    dw.make_solver(again, "dftl").advance(state, again.control(), 0.01, 2)


# -- 4. short writes ---------------------------------------------------------------------------------


def test_state_writes_of_another_row_count_are_refused(m32):
    state = m32.state()
    with pytest.raises(ValueError, match=r"positions must have shape \(10, 3\) .* got \(3, 3\)"):
        state.write("positions", np.zeros((3, 3)))
    with pytest.raises(ValueError, match=r"velocities must have shape \(10, 3\) .* got \(4, 3\)"):
        state.velocities.assign(np.ones((4, 3)))
    state.velocities.assign(np.ones((10, 3)))
    assert (state.velocities.numpy() == 1).all()


# -- 5. coerced or obscure option values ---------------------------------------------------------------


@pytest.mark.parametrize("options, message", [
    ({"damping": "0.5"}, r"damping must be in \[0, 1\], got '0.5'"),
    ({"damping": True}, r"damping must be in \[0, 1\], got True"),
    ({"youngs_modulus": "1e9"}, r"youngs_modulus must be > 0 and finite, got '1e9'"),
    ({"youngs_modulus": None}, r"youngs_modulus must be > 0 and finite, got None"),
    ({"density": "1300"}, r"density must be > 0 and finite, got '1300'"),
    ({"twist_modulus": None}, r"twist_modulus must be > 0 and finite, got None"),
    ({"drag": "1"}, r"drag must be >= 0 and finite, got '1'"),
    ({"rest_shape": "bogus"}, r"rest_shape must be 10 finite points .* got 'bogus'"),
])
def test_elastic_options_that_are_not_numbers_are_refused(m32, options, message):
    with pytest.raises(ValueError, match=message):
        dw.make_solver(m32, "elastic", **options)


def test_other_coerced_values_are_refused(m64):
    points, counts = _two()
    with pytest.raises(ValueError, match="elastic must be True, False, None or a dict of elastic options, got 'yes'"):
        dw.make_solver(m64, "reference", elastic="yes")
    with pytest.raises(ValueError, match=r"elastic: youngs_modulus must be > 0 and finite, got '1e9'"):
        dw.make_solver(m64, "reference", elastic={"youngs_modulus": "1e9"})
    with pytest.raises(ValueError, match="sphere radius must be a finite number, got '1'"):
        F.Sphere(radius="1")
    with pytest.raises(ValueError, match="sphere radius must be a finite number, got True"):
        F.Sphere(radius=True)
    with pytest.raises(ValueError, match=r"drag rate must be a number or one per strand \(1/s\), got '1'"):
        F.Drag("1")
    with pytest.raises(ValueError, match="corrections must be True or False, got 'no'"):
        dw.Model.from_strands(points, counts, corrections="no")


# -- 6. constructors given something other than a Model ------------------------------------------------


@pytest.mark.parametrize("cls, arg, shown", [(DFTLSolver, None, "None"), (PBDSolver, np.zeros((3, 3)), "ndarray"),
                                             (ReferenceSolver, None, "None")])
def test_solver_constructors_name_the_model(cls, arg, shown):
    with pytest.raises(TypeError, match=f"model must be a dftl_warp Model .* got {shown}"):
        cls(arg)


def test_simulation_names_scene_and_options():
    from dftl_warp.simulation.simulate import Simulation, SimulationOptions

    with pytest.raises(TypeError, match="scene must be a dftl_warp Scene .* got NoneType"):
        Simulation(None, SimulationOptions(), 1)
    with pytest.raises(TypeError, match="options must be a dftl_warp SimulationOptions, got dict"):
        Simulation(object.__new__(dw.Scene), {"substeps": 4}, 1)


# -- 7. make_solver warns about options the solver does not take -----------------------------------------


def test_make_solver_warns_about_dropped_options(m32):
    with pytest.warns(UserWarning, match=r"damping 0.5 does nothing here: this solver is not the dftl or elastic"):
        dw.make_solver(m32, "ftl", damping=0.5)
    with pytest.warns(UserWarning, match="iterations 8 does nothing here"):
        dw.make_solver(m32, "dftl", iterations=8)
    with pytest.warns(UserWarning, match="youngs_modulus 1000000000.0 does nothing here: the dftl solver does not"):
        dw.make_solver(m32, "dftl", youngs_modulus=1e9)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        dw.make_solver(m32, "pbd", damping=1.0, correction="prior", iterations=4)   # defaults, or taken
        # simulate_strands warns once, not once more from make_solver
        with pytest.warns(UserWarning) as caught:
            dw.simulate_strands(*_two(), steps=1, dt=0.01, solver="pbd", damping=0.5)
    assert len(caught) == 1


def _unread_scene():
    """A Scene object and options for the checks Simulation makes before it reads the scene."""
    from dftl_warp.simulation.simulate import SimulationOptions

    return object.__new__(dw.Scene), SimulationOptions()


@pytest.mark.parametrize("frame", [1.5, "1", True])
def test_a_simulation_frame_must_be_a_whole_frame_number(frame):
    from dftl_warp.simulation.simulate import Simulation

    with pytest.raises(ValueError, match="frame must be a whole frame number"):   # 1.5 was truncated to 1
        Simulation(*_unread_scene(), frame)


@pytest.mark.parametrize("tolerance", [-1.0, float("nan"), 0.0])
def test_a_simulation_tolerance_is_checked_as_simulate_usd_checks_it(tolerance):
    from dftl_warp.simulation.simulate import Simulation

    with pytest.raises(ValueError, match="tolerance"):   # -1 and NaN were accepted
        Simulation(*_unread_scene(), 1, tolerance=tolerance)


def test_one_feature_or_shape_given_alone_says_it_wants_a_list():
    pts = np.array([[0.0, 0.0, 0.0], [0.0, -0.1, 0.0], [0.0, -0.2, 0.0]])
    with pytest.raises(TypeError, match=r"features must be a list of feature objects .* got one Drag: "
                                        r"features=\[Drag\(\.\.\.\)\]"):
        dw.Model.from_strands(pts, [3], device="cpu", features=F.Drag(1.0))
    with pytest.raises(TypeError, match=r"shapes must be a list of shapes, got one Sphere: Colliders\(\[Sphere"):
        F.Colliders(F.Sphere(radius=1.0))


@pytest.mark.parametrize("call", ["simulate_usd", "read_scene", "read_groom", "import_groom"])
def test_a_path_of_none_names_the_argument(tmp_path, call):
    from dftl_warp.importers import import_groom, read_groom
    from dftl_warp.simulation.simulate import simulate_usd
    from dftl_warp.usd.read import read_scene

    run = {"simulate_usd": lambda: simulate_usd(None, str(tmp_path / "o.usdc")),
           "read_scene": lambda: read_scene(None), "read_groom": lambda: read_groom(None),
           "import_groom": lambda: import_groom(None, str(tmp_path / "o.usda"))}[call]
    name = {"simulate_usd": "input", "read_scene": "source", "read_groom": "path", "import_groom": "source"}[call]
    with pytest.raises(TypeError, match=rf"^{name} must be a file path \(str or os.PathLike\), got None$"):
        run()
    assert not list(tmp_path.iterdir())
