#!/usr/bin/env bash
# Run the CPU test suite on a CUDA device, to catch what only the GPU does (its particle layout,
# CUDA graphs, the three-kernel elastic step, warp-aggregated atomics): docs/gpu-checks.md.
#
#   bash scripts/gpu_suite.sh [DEVICE] [pytest arguments...]     (DEVICE default cuda:0)
#   JOBS=8 bash scripts/gpu_suite.sh cuda:0                         (8 pytest processes, the test
#                                                                    files dealt round-robin)
#
# The working tree's files (those git does not ignore, as they are) are copied to a temporary folder; there every "cpu" device
# of the tests and the library's CPU defaults become DEVICE, and a pytest plugin runs every
# Simulation on DEVICE. The working tree is not touched. Many tests assert what only the CPU does
# (bitwise equality of two kernels, its default device or layout, launch counts that a CUDA graph
# replays without launching): docs/gpu-checks.md lists them, so read failures against that list.
set -euo pipefail
device="${1:-cuda:0}"
[ $# -gt 0 ] && shift
root="$(cd "$(dirname "$0")/.." && pwd)"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
if git -C "$root" ls-files > /dev/null 2>&1; then   # the working tree's files (not ignored), as they are
  (cd "$root" && git ls-files -co --exclude-standard -z | tar --null -T - -cf -) | tar -x -C "$work"
else   # a copy of the tree without a usable git folder: every file but the hidden ones
  tar -C "$root" --exclude=./.git --exclude='./.[a-z]*' -cf - . | tar -x -C "$work"
fi
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
export PYTHONPATH="$work:$work/tests:${PYTHONPATH:-}"
jobs="${JOBS:-1}"
if [ "$jobs" -le 1 ]; then
  python -m pytest -p gpu_suite_plugin -p no:cacheprovider -q -rf "$@"
  exit
fi
files=(); options=()
for a in "$@"; do if [ -e "$a" ]; then files+=("$a"); else options+=("$a"); fi; done
if [ ${#files[@]} -eq 0 ]; then ls tests/test_*.py > "$work/files"; else printf "%s\n" "${files[@]}" > "$work/files"; fi
split -n "r/$jobs" "$work/files" "$work/shard_"
status=0
for shard in "$work"/shard_*; do
  [ -s "$shard" ] || continue
  python -m pytest -p gpu_suite_plugin -p no:cacheprovider -q -rf "${options[@]}" $(cat "$shard") > "$shard.log" 2>&1 &
done
for job in $(jobs -p); do wait "$job" || status=1; done
grep -h "^FAILED\|^ERROR" "$work"/shard_*.log || true
tail -qn 1 "$work"/shard_*.log 2>/dev/null
exit $status
