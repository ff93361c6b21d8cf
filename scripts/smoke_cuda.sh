# CLI smoke test on a CUDA machine: every command on cuda:0 (run from the repository root;
# $OUT receives the GPU-rendered preview). Used for docs/benchmarks.md, "The command line on CUDA".
set -e
mkdir -p /tmp/gpu_out
dftl() { python3 -m dftl_warp "$@"; }
dftl devices
dftl info scenes/default.usda
dftl simulate scenes/default.usda -o /tmp/gpu_out/demo.usdc --device cuda:0 --quiet
python3 - <<'PY'
import numpy as np
from pxr import Usd, UsdGeom
a = Usd.Stage.Open("/tmp/gpu_out/demo.usdc")
pa = np.array(UsdGeom.BasisCurves(a.GetPrimAtPath("/World/Head/Hair")).GetPointsAttr().Get(72))
seg = np.linalg.norm(np.diff(pa.reshape(-1, 16, 3), axis=1), axis=2)
print("cuda frame 72: finite", np.isfinite(pa).all(), "segments", seg.min(), seg.max(), "cm")
PY
dftl render /tmp/gpu_out/demo.usdc --frame 30 --resolution 1920x1080 --spp 8 --device cuda:0 -o $OUT/demo_gpu.png
dftl batch scripts/smoke_cuda_jobs.toml --quiet
dftl simulate scenes/default.usda -o /tmp/gpu_out/q.usdc --device cuda:0 --quality production --quiet
dftl simulate scenes/default.usda -o /tmp/gpu_out/x.usdc --device cuda:1 --quiet || echo "(expected: no cuda:1 here)"
