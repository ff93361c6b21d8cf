#!/usr/bin/env bash
# Run the CPU test suite on a CUDA device, to catch what only the GPU does (its particle layout,
# CUDA graphs, the three-kernel elastic step, warp-aggregated atomics): docs/gpu-checks.md.
#
#   bash scripts/gpu_suite.sh [DEVICE] [pytest arguments...]     (DEVICE default cuda:0)
#
# The committed tree (git archive HEAD) is copied to a temporary folder; there every "cpu" device
# of the tests and the library's CPU defaults become DEVICE, and a pytest plugin runs every
# Simulation on DEVICE. The working tree is not touched. Many tests assert what only the CPU does
# (bitwise equality of two kernels, its default device or layout, launch counts that a CUDA graph
# replays without launching): docs/gpu-checks.md lists them, so read failures against that list.
set -euo pipefail
device="${1:-cuda:0}"
[ $# -gt 0 ] && shift
root="$(git -C "$(dirname "$0")/.." rev-parse --show-toplevel)"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
git -C "$root" archive HEAD | tar -x -C "$work"
cd "$work"
# an editable install maps dftl_warp.kernels to the repository's kernels/; elsewhere link it
PYTHONPATH="$work" python -c "import dftl_warp.kernels" 2>/dev/null || ln -s ../kernels dftl_warp/kernels
sed -i "s/device=\"cpu\", shading/device=\"$device\", shading/" dftl_warp/render/renderer.py
sed -i "s/def __init__(self, binding: Binding, device=\"cpu\")/def __init__(self, binding: Binding, device=\"$device\")/" \
    dftl_warp/guides/deform.py
sed -i "s/^    device: str = \"cpu\",/    device: str = \"$device\",/" dftl_warp/simulation/strands.py
sed -i "s/^        device=\"cpu\",/        device=\"$device\",/" dftl_warp/core/model.py
sed -i "s/\*, device=\"cpu\", precision/*, device=\"$device\", precision/" dftl_warp/core/synthetic.py
sed -i "s/device: str = \"cpu\"/device: str = \"$device\"/" dftl_warp/study/front.py dftl_warp/study/sweeps.py
for f in tests/*.py; do
  sed -i -e "s/\"cpu,cpu\"/\"$device,$device\"/g" -e "s/'cpu'/'$device'/g" -e "s/\"cpu\"/\"$device\"/g" "$f"
done
cat > tests/gpu_suite_plugin.py <<PY
"""Every Simulation whose options name the CPU runs on $device."""
import dataclasses

import dftl_warp.simulation.simulate as simulate

_init = simulate.Simulation.__init__


def _on_device(self, scene, options, *a, **k):
    if options.device in ("cpu", "cpu,cpu", None):
        options = dataclasses.replace(options, device="$device")
    return _init(self, scene, options, *a, **k)


simulate.Simulation.__init__ = _on_device
PY
PYTHONPATH="$work:$work/tests:${PYTHONPATH:-}" python -m pytest -p gpu_suite_plugin -p no:cacheprovider -q -rf "$@"
