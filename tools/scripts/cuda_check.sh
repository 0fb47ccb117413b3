#!/usr/bin/env bash
# The GPU checks behind docs/platforms.md, docs/compositions.md and docs/benchmarks.md, in one
# short run on a machine with CUDA (OpenMM and its CUDA plugin importable, e.g. from carried wheels):
#   1. the common-platform and rescaling tests on CUDA, mixed and single precision, beside
#   2. long NVE runs of the default programs (energy benchmark, CUDA mixed: tip3p-3nm 20 ps,
#      villin 10 ps; RATTLE, RATTLE-4 + rescaling, the α-RATTLE-4 energy mode, RATTLE at h/k);
#   3. then alone on the GPU, the cost benchmark (every program) on 2.7k-, 21k- and 72k-atom
#      TIP3P boxes in mixed precision and on the 21k box in single precision.
# Usage: OUT=folder tools/scripts/cuda_check.sh   (eight files: log.txt, cuda_tests.log,
# energy_tip3p-3nm.json, energy_villin.json, cost_3.json, cost_6.json, cost_9.json, cost_6_single.json)
set -uo pipefail
OUT=${OUT:-cuda-check}
mkdir -p "$OUT"
export PYTHONUNBUFFERED=1
BENCH='import sys, importlib; sys.exit(importlib.import_module("openmm_alphaprk.benchmarks." + sys.argv[1]).main(sys.argv[2:]))'
PLATFORM=${PLATFORM:-CUDA}
{
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader
python3 -c "import openmm; print('OpenMM', openmm.__version__)"
start=$SECONDS
ALPHAPRK_TEST_PLATFORMS=$PLATFORM:mixed,$PLATFORM:single ALPHAPRK_REQUIRE_PLATFORMS=1 \
    timeout 240 python3 -m pytest -q -p no:cacheprovider --durations=5 \
    tests/test_common_platform.py tests/test_rescale.py >"$OUT/cuda_tests.log" 2>&1 &
tests=$!
(
    timeout 130 python3 -c "$BENCH" energy --platform "$PLATFORM" --precision mixed --system tip3p-3nm --time 20 --fixed-alpha \
        --only rattle4+rescale energy4 --json "$OUT/energy_tip3p-3nm.json" 2>&1 | grep -v "it/s\]" | tail -12
    timeout 120 python3 -c "$BENCH" energy --platform "$PLATFORM" --precision mixed --system villin --time 10 --fixed-alpha \
        --only rattle4+rescale energy4 --json "$OUT/energy_villin.json" 2>&1 | grep -v "it/s\]" | tail -12
)
wait $tests
echo "tests (exit $?, $((SECONDS - start)) s):"; tail -12 "$OUT/cuda_tests.log"
for run in "3 mixed 50" "6 mixed 70" "9 mixed 100" "6 single 70"; do
    set -- $run
    name=cost_$1$([ "$2" = single ] && echo _single)
    echo "== cost, box $1 nm, $2 ($((SECONDS - start)) s)"
    timeout "$3" python3 -c "$BENCH" cost --platform "$PLATFORM" --precision "$2" --box "$1" --steps 100 --rounds 3 --energy-steps 10 \
        --equilibration-steps 100 --integrators all --json "$OUT/$name.json" 2>&1 | grep -v "^round\|^energy pass" | tail -14
done
echo "done in $((SECONDS - start)) s"
} 2>&1 | tee "$OUT/log.txt"
