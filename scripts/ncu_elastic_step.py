#!/usr/bin/env python3
"""A few elastic steps without CUDA graphs, for Nsight Compute to profile one launch of the kernel
(scripts/bench_elastic.py's curly groom, float32 arithmetic):

    ncu --kernel-name regex:elastic_step --launch-skip 1 --launch-count 1 --section SpeedOfLight \\
        --section Occupancy --section LaunchStats --section WarpStateStats \\
        python scripts/ncu_elastic_step.py 262144
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))


def main() -> int:
    import warp as wp

    wp.config.quiet = True
    wp.init()

    import dftl_warp as dw
    from bench_elastic import curly_groom

    pts, counts = curly_groom(int(sys.argv[1]) if len(sys.argv) > 1 else 262144)
    model = dw.Model.from_strands(pts, counts, device=sys.argv[2] if len(sys.argv) > 2 else "cuda:0", widths=80e-6)
    solver = dw.make_solver(model, "elastic", compute_precision="float32")
    state, control = solver.state(), model.control()
    for _ in range(3):
        solver.step(state, state, control, 1.0 / 192)
    wp.synchronize()
    print("done")
    return 0


if __name__ == "__main__":
    sys.exit(main())
