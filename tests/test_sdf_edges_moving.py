"""Hair sliding around an edge of a box moved by its pose stays outside it when the box collides
through its signed distance field.

The 8 cm box mesh of ``test_mesh_edges_moving.py`` with a field (5 mm cells), moved by its pose
through hanging hair: the strands wrap around its front edges, a particle on the bottom face and its
leader on the front face. Before, the field answered such a particle on the bottom face's contact
plane (the trace's stop there, or the projection along the field's gradient), 20.2 mm behind the
leader for 20 mm segments: no point at the rest length clears that plane, and the rest length
restored along the segment pulled the particle back inside the box, its followers after it (11.5 mm
deep at 2 m/s with the default 2 collision rounds, 12.8 mm at 1 m/s with one). Now the field hands
such a contact to the exact mesh query, which answers by the face the segment from the leader
enters the box through (the mesh path's rule for the same edge).

The depth is the box's analytic signed distance where the simulation puts the box (its pose moves
at a constant speed, linear within each frame as the substeps interpolate it). The run counts the
field's tests by outcome (``kernels.features.mesh.COUNT_FIELD_TESTS``, set before its kernels are
built, so in a process of its own: this file run as a script).
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from dftl_warp.kernels.features import mesh as mesh_kernels
from dftl_warp.kernels.features.sdf import EXACT_FROM, WHY_EXACT
from test_deforming_motion import RADIUS
from test_mesh_edges_moving import push_through

OUT_OF_REACH = WHY_EXACT[10]


def push_through_field(speed: float, iterations: int) -> dict:
    """The field-collided box moved by its pose at ``speed`` (m/s) through the hair: the deepest
    any non-root particle is inside it over every substep (m), how far it pushed the hair (m), and
    its field's tests by outcome."""
    worst, reach, control = push_through("pose", speed, iterations, sdf=True, sdf_cell=0.005)
    tests = control.features.colliders.kind_data["meshes"].fields.tests()
    return dict(worst=worst, reach=reach, tests=tests)


@pytest.mark.parametrize("speed, iterations", [(1.0, 2), (2.0, 2), (1.0, 1)])
def test_no_particle_enters_a_field_collided_box_moving_through_hair(speed, iterations):
    """At 1 and 2 m/s with the default 2 collision rounds and at 1 m/s with one (the continuous
    test alone), no non-root particle is more than 2 hair radii inside the box at any substep
    (before: 0, 11.5 and 12.8 mm), the box did push the hair (10 cm on), and the field answered
    most of the tests (the box's field collided it); the contacts round the edge went to the exact
    query."""
    done = subprocess.run([sys.executable, __file__, str(speed), str(iterations)], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-2000:]
    run = json.loads(done.stdout.strip().splitlines()[-1])
    assert run["reach"] > 0.1
    assert run["worst"] < 2 * RADIUS, f"{run['worst'] * 1e3:.2f} mm inside"
    tests = run["tests"]
    answered = sum(tests[w] for w in WHY_EXACT[:EXACT_FROM])
    assert answered > 0.5 * sum(tests.values()), tests
    assert tests[OUT_OF_REACH] > 0, tests


if __name__ == "__main__":
    mesh_kernels.COUNT_FIELD_TESTS = True  # before the first step builds the kernels
    print(json.dumps(push_through_field(float(sys.argv[1]), int(sys.argv[2]))))
