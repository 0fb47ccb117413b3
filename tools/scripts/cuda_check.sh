#!/usr/bin/env bash
# The GPU checks behind docs/long_runs.md, docs/platforms.md and docs/benchmarks.md, in one run
# of at most 9 minutes on a machine with CUDA (OpenMM and its CUDA plugin importable, e.g. from
# carried wheels; the package importable from the checkout):
#   A. at the same time: the common-platform and rescaling tests on CUDA (mixed and single), and
#      `alphaprk bench long` on a water box in mixed precision, the rows one after the other in one
#      process (the one-evaluation rows LONG_TIME ps, the others MULTI_TIME ps; stopped with
#      SIGTERM after LONG_LIMIT s, which keeps what it ran), then its report. Rows in processes of
#      their own (a comma-free GROUPS_OF_ROWS) share the GPU by time-slicing, which slows the rows
#      that synchronise with the host every step many times over (seen on an H100, 2026-11-27);
#      single precision does not conserve energy (the same run), so LONG_PRECISIONS is mixed;
#   B. then alone on the GPU: `alphaprk bench cost` on each of COST_SYSTEMS (mixed), on DHFR with
#      the package's settings at 2 fs, and OpenMM's DHFR benchmark system as OpenMM builds it at
#      4 fs (openmm_alphaprk.benchmarks.dhfr_openmm_settings), for ns/day beside OpenMM's published figure;
#   C. the explicit family's survey (tools/scripts/splitting_survey.py) on villin at 2 fs and on
#      dhfr at 4 fs with hydrogens of 3 amu (its start "dhfr-h3" built beforehand like dhfr); off by
#      default since docs/splitting.md has its CPU tables (SURVEYS=1 runs it);
#   D. the physics stress test on a larger box (docs/physics.md): `alphaprk bench physics stress` of
#      RATTLE + rescaling beside RATTLE, PHYSICS_TIME ps at 4 fs on PHYSICS_SYSTEM in mixed precision
#      (stopped after PHYSICS_LIMIT s, which keeps what it ran), then its report (partition
#      temperatures in windows) as $OUT/physics.json.
# Usage: OUT=folder tools/scripts/cuda_check.sh
# The 21k- and 72k-atom boxes (tools/scripts/systems/*.toml) and dhfr are built and equilibrated
# on first use, minutes on the CPU: build them before the GPU is lent and carry the cache, e.g.
#   ALPHAPRK_CACHE_DIR=$PWD/.devcache python -c "from openmm_alphaprk.systems import prepare_system as p;
#       [p(n) for n in ('tools/scripts/systems/tip3p-6nm.toml', 'tools/scripts/systems/tip3p-9nm.toml', 'dhfr')];
#       from openmm_alphaprk.systems import load_definition as d; p(d('dhfr').with_hydrogen_mass(3))"
# then on the GPU machine export ALPHAPRK_CACHE_DIR to the carried folder (the key holds the
# definition's content and OpenMM's version).
# Files: $OUT/log.txt (everything printed), $OUT/long.tar.gz (test log, long-run folders without
# checkpoints and trajectories; written when part A ends) and $OUT/cost.tar.gz (cost JSONs). Knobs (environment): PLATFORM (CUDA),
# PRECISIONS of the tests ("mixed single"), LONG_PRECISIONS ("mixed"), LONG_SYSTEM (tip3p-3nm),
# LONG_TIME (250), MULTI_TIME (100), LONG_LIMIT (300), TEST_LIMIT (280), COST_SYSTEMS, COST_STEPS
# (200), COST_ROUNDS (3), DHFR (1), SURVEYS (0), TESTS (the test files; "none": no tests), GROUPS_OF_ROWS,
# PHYSICS (1), PHYSICS_SYSTEM (tip3p-3nm), PHYSICS_TIME (200), PHYSICS_LIMIT (150).
set -uo pipefail
OUT=${OUT:-cuda-check}
mkdir -p "$OUT"
OUT=$(cd "$OUT" && pwd)
WORK=${WORK:-$(mktemp -d)}
export PYTHONUNBUFFERED=1
PLATFORM=${PLATFORM:-CUDA}
PRECISIONS=${PRECISIONS:-mixed single}
LONG_SYSTEM=${LONG_SYSTEM:-tip3p-3nm}
LONG_PRECISIONS=${LONG_PRECISIONS:-mixed}
LONG_TIME=${LONG_TIME:-250}
MULTI_TIME=${MULTI_TIME:-100}
LONG_LIMIT=${LONG_LIMIT:-300}
TEST_LIMIT=${TEST_LIMIT:-280}
COST_SYSTEMS=${COST_SYSTEMS:-tip3p-3nm tools/scripts/systems/tip3p-6nm.toml tools/scripts/systems/tip3p-9nm.toml}
COST_STEPS=${COST_STEPS:-200}
COST_ROUNDS=${COST_ROUNDS:-3}
DHFR=${DHFR:-1}
SURVEYS=${SURVEYS:-0}
PHYSICS=${PHYSICS:-1}
PHYSICS_SYSTEM=${PHYSICS_SYSTEM:-tip3p-3nm}
PHYSICS_TIME=${PHYSICS_TIME:-200}
PHYSICS_LIMIT=${PHYSICS_LIMIT:-150}
TESTS=${TESTS:-tests/test_common_platform.py tests/test_rescale.py}
ALPHAPRK="python3 -m openmm_alphaprk"
# the rows of bench long; one process per group (a comma joins rows that run one after the other)
INTERVAL_ROWS="rattle+rescale@10 rattle4+rescale@10"
GROUPS_OF_ROWS=${GROUPS_OF_ROWS:-verlet,rattle,rattle+rescale,rattle+rescale@10,split-me,split-me+rescale,alpha4=0,rattle4+rescale,energy4}
# the explicit family's rows of bench cost
SPLIT_ROWS="split-me split-me+rescale split3-me"
ROWS=${GROUPS_OF_ROWS//,/ }
{
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader 2>/dev/null || echo "no nvidia-smi"
python3 -c "import openmm; print('OpenMM', openmm.__version__)"
start=$SECONDS
echo "== A: tests and long runs ($PLATFORM; rows: $ROWS)"
tests=""
if [ "$TESTS" != none ]; then
    test_platforms=$(for p in $PRECISIONS; do printf '%s:%s,' "$PLATFORM" "$p"; done)
    ALPHAPRK_TEST_PLATFORMS=${test_platforms%,} ALPHAPRK_REQUIRE_PLATFORMS=1 \
        timeout "$TEST_LIMIT" python3 -m pytest -q -p no:cacheprovider -n 3 --durations=5 \
        $TESTS >"$WORK/tests.log" 2>&1 &
    tests=$!
fi
pids=""
for precision in $LONG_PRECISIONS; do
    for group in $GROUPS_OF_ROWS; do
        timeout "$LONG_LIMIT" $ALPHAPRK bench long --system "$LONG_SYSTEM" --platform "$PLATFORM" \
            --precision "$precision" --time "$LONG_TIME" --time-multi "$MULTI_TIME" --integrators ${group//,/ } \
            --output "$WORK/long_$precision" --no-progress >"$WORK/long_${precision}_${group//[^a-z0-9]/_}.log" 2>&1 &
        pids="$pids $!"
    done
done
wait $pids
echo "long runs stopped or done after $((SECONDS - start)) s"
for precision in $LONG_PRECISIONS; do
    echo "-- bench long, $PLATFORM $precision (report of what ran)"
    $ALPHAPRK bench long --system "$LONG_SYSTEM" --platform "$PLATFORM" --precision "$precision" \
        --time "$LONG_TIME" --time-multi "$MULTI_TIME" --integrators $ROWS --output "$WORK/long_$precision" \
        --report --no-progress 2>&1 | grep -v "^ *$"
done
if [ -n "$tests" ]; then
    wait "$tests"
    echo "tests (exit $?, $((SECONDS - start)) s):"
    tail -15 "$WORK/tests.log"
fi
tar -C "$WORK" --exclude='*.chk' --exclude='*.chk.previous' --exclude='*.dcd' --exclude='system.xml' \
    -czf "$OUT/long.tar.gz" $(cd "$WORK" && ls -d long_* tests.log 2>/dev/null)
echo "== B: cost, alone on the GPU ($((SECONDS - start)) s)"
i=0
for system in $COST_SYSTEMS; do
    i=$((i + 1))
    echo "-- cost, $system, mixed ($((SECONDS - start)) s)"
    timeout 60 $ALPHAPRK bench cost --system "$system" --platform "$PLATFORM" --precision mixed \
        --steps "$COST_STEPS" --rounds "$COST_ROUNDS" --energy-steps 10 \
        --integrators verlet rattle rattle+rescale $INTERVAL_ROWS $SPLIT_ROWS alpha4=0 rattle4+rescale energy4 \
        --json "$WORK/cost_${i}_$(basename "$system" .toml).json" 2>&1 | grep -v "^round\|^energy pass\|unsupported OpenCL"
done
if [ "$DHFR" = 1 ]; then
    echo "-- cost, dhfr (package settings), 2 fs, mixed ($((SECONDS - start)) s)"
    timeout 70 $ALPHAPRK bench cost --system dhfr --platform "$PLATFORM" --precision mixed \
        --steps "$COST_STEPS" --rounds "$COST_ROUNDS" --energy-steps 10 \
        --integrators verlet rattle rattle+rescale $INTERVAL_ROWS $SPLIT_ROWS alpha4=0 rattle4+rescale \
        --json "$WORK/cost_dhfr_2fs.json" 2>&1 | grep -v "^round\|^energy pass\|unsupported OpenCL"
    echo "-- DHFR as OpenMM's benchmark builds it, 4 fs, mixed ($((SECONDS - start)) s)"
    timeout 50 python3 -m openmm_alphaprk.benchmarks.dhfr_openmm_settings --platform "$PLATFORM" --precision mixed \
        --integrators rattle rattle+rescale ${INTERVAL_ROWS%% *} split-me split-me+rescale rattle4+rescale \
        --steps 500 --rounds 3 \
        --json "$WORK/dhfr_openmm_settings.json" 2>&1
fi
if [ "$SURVEYS" = 1 ]; then
    echo "== C: the explicit family against RATTLE at equal force evaluations, mixed ($((SECONDS - start)) s)"
    two=(--rows "RATTLE at h" "RATTLE at h/2" split=1/4 split-bcss split-me split-me+rescale)
    timeout 90 python3 tools/scripts/splitting_survey.py --system villin --timestep 2 --platform "$PLATFORM" \
        --precision mixed --json "$WORK/survey_villin_2fs.json" 2>&1
    timeout 90 python3 tools/scripts/splitting_survey.py --system dhfr --timestep 4 --hydrogen-mass 3 \
        --platform "$PLATFORM" --precision mixed "${two[@]}" --json "$WORK/survey_dhfr_4fs_hmr3.json" 2>&1
fi
if [ "$PHYSICS" = 1 ]; then
    echo "== D: the physics stress test, $PHYSICS_SYSTEM at 4 fs, mixed ($((SECONDS - start)) s)"
    timeout -s TERM "$PHYSICS_LIMIT" $ALPHAPRK bench physics stress --system "$PHYSICS_SYSTEM" \
        --rows rattle+rescale rattle --timesteps 4 --time "$PHYSICS_TIME" --velocity-every 10 \
        --energy-every 5 --platform "$PLATFORM" --precision mixed --output "$WORK/physics" --no-progress 2>&1
    timeout 120 $ALPHAPRK bench physics report --output "$WORK/physics" --parts stress --windows 5 \
        --no-progress 2>&1 && cp "$WORK/physics/physics.json" "$OUT/physics.json"
fi
echo "done in $((SECONDS - start)) s"
} 2>&1 | tee "$OUT/log.txt"
tar -C "$WORK" -czf "$OUT/cost.tar.gz" $(cd "$WORK" && ls cost_*.json dhfr_*.json survey_*.json 2>/dev/null)
