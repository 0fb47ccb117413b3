#!/usr/bin/env bash
# The GPU checks behind docs/platforms.md and docs/accuracy.md, in one short run on a
# machine with CUDA (OpenMM and its CUDA plugin importable, e.g. from carried wheels):
#   1. the common-platform tests and the rescaling tests on CUDA, double and mixed;
#   2. the cost benchmark (RATTLE + rescaling among the core integrators) on 21k- and
#      72k-atom TIP3P boxes, CUDA mixed precision.
# Usage: OUT=folder tools/scripts/cuda_check.sh   (writes cuda_tests.log, cost_6.json, cost_9.json)
set -uo pipefail
OUT=${OUT:-cuda-check}
mkdir -p "$OUT"
export PYTHONUNBUFFERED=1
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader
python3 -c "import openmm; print('OpenMM', openmm.__version__)"
ALPHAPRK_TEST_PLATFORMS=CUDA:double,CUDA:mixed ALPHAPRK_REQUIRE_PLATFORMS=1 \
    timeout 240 python3 -m pytest -q -p no:cacheprovider --durations=5 \
    tests/test_common_platform.py tests/test_rescale.py 2>&1 | tee "$OUT/cuda_tests.log" | tail -8
for box in 6 9; do
    timeout 150 python3 -c "import sys; from openmm_alphaprk.benchmarks.cost import main; sys.exit(main(sys.argv[1:]))" \
        --platform CUDA --precision mixed --box "$box" --steps 200 --rounds 5 --energy-steps 20 \
        --equilibration-steps 200 --json "$OUT/cost_$box.json" 2>&1 | grep -v "^round" | tail -9
done
