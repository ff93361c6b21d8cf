"""A ``dftl:rootMesh`` whose only triangle is degenerate (zero area) failed with "root binding:
triangle index out of range", naming no prim or strand. Now it is one line naming the file, the
curves prim, the mesh prim and what is wrong, exit 2, and no output file."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import chain
from test_usd_bad_sizes import refused, stage

import dftl_warp as dw

DEGENERATE = ('    def Mesh "Head"\n    {\n        int[] faceVertexCounts = [3]\n'
              '        int[] faceVertexIndices = [0, 1, 2]\n'
              '        point3f[] points = [(0, 1, 0), (1, 1, 0), (2, 1, 0)]\n    }\n')


@pytest.mark.parametrize("solver", [[], ["--solver", "dftl"]])
def test_a_root_mesh_with_only_a_degenerate_triangle_is_refused_naming_both_prims(tmp_path, capfd, solver):
    path = stage(tmp_path, DEGENERATE, binding="rel dftl:rootMesh = </World/Head>")
    refused(tmp_path, capfd, path, r"/World/Hair: dftl:rootMesh -> /World/Head: no non-degenerate triangle to bind "
                                   r"the strands' roots to \(its triangle has zero area\)$", *solver)


def test_the_api_names_the_strand_a_degenerate_binding_mesh_cannot_hold():
    from dftl_warp import features as F

    scalp = np.array([[0.0, 0, 0], [1.0, 0, 0], [2.0, 0, 0]])
    with pytest.raises(ValueError, match=r"root binding: no non-degenerate triangle to bind strand 0's root to"):
        dw.Model.from_strands(chain(4, 0.02, direction=(0, -1, 0)), [4],
                              features=[F.RootBinding(scalp, np.array([[0, 1, 2]]))])
