#!/usr/bin/env bash
# The GPU checks behind docs/long_runs.md, docs/platforms.md and docs/benchmarks.md, in one run
# of at most 9 minutes on a machine with CUDA (OpenMM and its CUDA plugin importable, e.g. from
# carried wheels; the package importable from the checkout):
#   A. at the same time: the common-platform and rescaling tests on CUDA (mixed and single), and
#      `alphaprk bench long` in mixed precision at LONG_TIMESTEP fs with hydrogens of LONG_HMASS amu,
#      on each of LONG_SYSTEMS ("system:ps" pairs) one after the other, the rows (GROUPS_OF_ROWS: RATTLE,
#      rescaling every step, every 10th and every 100th) one after the other in one process (stopped with SIGTERM
#      after LONG_LIMIT s, which keeps what it ran), then its report. Rows in processes of their own
#      (a comma-free GROUPS_OF_ROWS) share the GPU by time-slicing, which slows the rows that
#      synchronise with the host every step many times over (seen on an H100, 2026-11-27); single
#      precision does not conserve energy (the same run), so the long runs are mixed;
#   B. then alone on the GPU: `alphaprk bench cost` on each of COST_SYSTEMS (mixed, 2 fs), on DHFR with
#      the package's settings at 4 fs with hydrogens of 3 amu, and OpenMM's DHFR benchmark system as
#      OpenMM builds it at 4 fs (openmm_alphaprk.benchmarks.dhfr_openmm_settings), for ns/day beside
#      OpenMM's published figure and LangevinMiddleIntegrator's, then the same with the package's
#      smooth forces (--smooth);
#   C. the explicit family's survey (tools/scripts/splitting_survey.py) on villin at 2 fs and on
#      dhfr at 4 fs with hydrogens of 3 amu (its start "dhfr-h3" built beforehand like dhfr); off by
#      default since docs/splitting.md has its CPU tables (SURVEYS=1 runs it);
#   D. the physics stress test on a larger box (docs/physics.md): `alphaprk bench physics stress` of
#      RATTLE + rescaling beside RATTLE, PHYSICS_TIME ps at 4 fs on PHYSICS_SYSTEM in mixed precision
#      (stopped after PHYSICS_LIMIT s, which keeps what it ran), then its report (partition
#      temperatures in windows) as $OUT/physics.json; off by default (PHYSICS=1 runs it).
# Usage: OUT=folder tools/scripts/cuda_check.sh
# The 21k- and 72k-atom boxes (tools/scripts/systems/*.toml), dhfr and the starts with hydrogens of
# 3 amu are built and equilibrated on first use, minutes on the CPU: build them before the GPU is
# lent and carry the cache, e.g.
#   ALPHAPRK_CACHE_DIR=$PWD/.devcache python -c "from openmm_alphaprk.systems import prepare_system as p;
#       [p(n) for n in ('tools/scripts/systems/tip3p-6nm.toml', 'dhfr')];
#       from openmm_alphaprk.systems import load_definition as d;
#       [p(d(n).with_hydrogen_mass(3)) for n in ('villin', 'dhfr')]"
# then on the GPU machine export ALPHAPRK_CACHE_DIR to the carried folder (the key holds the
# definition's content and OpenMM's version).
# Files: $OUT/log.txt (everything printed), $OUT/long.tar.gz (test log, long-run folders without
# checkpoints and trajectories; written when part A ends) and $OUT/cost.tar.gz (cost JSONs). Knobs
# (environment): PLATFORM (CUDA), PRECISIONS of the tests ("mixed single"), LONG_SYSTEMS
# ("villin:1000 dhfr:200"), LONG_TIMESTEP (4), LONG_HMASS (3; empty: none, for water), LONG_LIMIT (330),
# TEST_LIMIT (300), COST_SYSTEMS, COST_STEPS (200), COST_ROUNDS (3), COST_LIMIT (60 s per system), DHFR (1), SURVEYS (0), TESTS
# (the test files; "none": no tests), GROUPS_OF_ROWS, PHYSICS (0), PHYSICS_SYSTEM (tip3p-3nm),
# PHYSICS_TIME (200), PHYSICS_LIMIT (150).
set -uo pipefail
OUT=${OUT:-cuda-check}
mkdir -p "$OUT"
OUT=$(cd "$OUT" && pwd)
WORK=${WORK:-$(mktemp -d)}
mkdir -p "$WORK"
export PYTHONUNBUFFERED=1
PLATFORM=${PLATFORM:-CUDA}
PRECISIONS=${PRECISIONS:-mixed single}
LONG_SYSTEMS=${LONG_SYSTEMS:-villin:1000 dhfr:200}
LONG_TIMESTEP=${LONG_TIMESTEP:-4}
LONG_HMASS=${LONG_HMASS-3}
LONG_LIMIT=${LONG_LIMIT:-330}
TEST_LIMIT=${TEST_LIMIT:-300}
COST_SYSTEMS=${COST_SYSTEMS:-tip3p-3nm tools/scripts/systems/tip3p-6nm.toml}
COST_STEPS=${COST_STEPS:-200}
COST_LIMIT=${COST_LIMIT:-60}
COST_ROUNDS=${COST_ROUNDS:-3}
DHFR=${DHFR:-1}
SURVEYS=${SURVEYS:-0}
PHYSICS=${PHYSICS:-0}
PHYSICS_SYSTEM=${PHYSICS_SYSTEM:-tip3p-3nm}
PHYSICS_TIME=${PHYSICS_TIME:-200}
PHYSICS_LIMIT=${PHYSICS_LIMIT:-150}
TESTS=${TESTS:-tests/test_common_platform.py tests/test_rescale.py}
ALPHAPRK="python3 -m openmm_alphaprk"
# the rows of bench long; one process per group (a comma joins rows that run one after the other)
GROUPS_OF_ROWS=${GROUPS_OF_ROWS:-rattle,rattle+rescale,rattle+rescale@10,rattle+rescale@100}
ROWS=${GROUPS_OF_ROWS//,/ }
# the rows of bench cost: the intervals beside every step and RATTLE
INTERVAL_ROWS="rattle+rescale@10 rattle+rescale@100 rattle4+rescale@10"
COST_ROWS="verlet rattle rattle+rescale $INTERVAL_ROWS rattle4+rescale split-me+rescale"
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
export ALPHAPRK LONG_SYSTEMS LONG_TIMESTEP LONG_HMASS PLATFORM WORK
for group in $GROUPS_OF_ROWS; do
    # the systems one after the other, each over its own ps; timeout's SIGTERM goes to the whole
    # group: the run keeps what it ran, and the loop starts no other system after it
    timeout "$LONG_LIMIT" bash -c 'trap "stopped=1" TERM; for pair in $LONG_SYSTEMS; do
        [ -n "${stopped:-}" ] && break
        $ALPHAPRK bench long --system "${pair%%:*}" --time "${pair##*:}" --timestep "$LONG_TIMESTEP" \
            ${LONG_HMASS:+--hydrogen-mass $LONG_HMASS} --platform "$PLATFORM" --precision mixed --integrators ${1//,/ } \
            --output "$WORK/long_mixed" --no-progress
    done' rows "$group" >"$WORK/long_mixed_${group//[^a-z0-9]/_}.log" 2>&1 &
    pids="$pids $!"
done
wait $pids
echo "long runs stopped or done after $((SECONDS - start)) s"
for pair in $LONG_SYSTEMS; do
    echo "-- bench long, ${pair%%:*}, $PLATFORM mixed (report of what ran)"
    $ALPHAPRK bench long --system "${pair%%:*}" --time "${pair##*:}" --timestep "$LONG_TIMESTEP" \
        ${LONG_HMASS:+--hydrogen-mass $LONG_HMASS} --platform "$PLATFORM" --precision mixed --integrators $ROWS \
        --output "$WORK/long_mixed" --report --no-progress 2>&1 | grep -v "^ *$"
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
    timeout "$COST_LIMIT" $ALPHAPRK bench cost --system "$system" --platform "$PLATFORM" --precision mixed \
        --steps "$COST_STEPS" --rounds "$COST_ROUNDS" --energy-steps 10 --integrators $COST_ROWS \
        --json "$WORK/cost_${i}_$(basename "$system" .toml).json" 2>&1 | grep -v "^round\|^energy pass\|unsupported OpenCL"
done
if [ "$DHFR" = 1 ]; then
    echo "-- cost, dhfr (package settings), 4 fs, hydrogens 3 amu, mixed ($((SECONDS - start)) s)"
    timeout "$((COST_LIMIT + 10))" $ALPHAPRK bench cost --system dhfr --timestep 4 --hydrogen-mass 3 --platform "$PLATFORM" \
        --precision mixed --steps "$COST_STEPS" --rounds "$COST_ROUNDS" --energy-steps 10 --integrators $COST_ROWS \
        --json "$WORK/cost_dhfr_4fs_hmr3.json" 2>&1 | grep -v "^round\|^energy pass\|unsupported OpenCL"
    for forces in openmm smooth; do
        echo "-- DHFR as OpenMM's benchmark builds it, 4 fs, mixed, $forces forces ($((SECONDS - start)) s)"
        timeout 50 python3 -m openmm_alphaprk.benchmarks.dhfr_openmm_settings --platform "$PLATFORM" --precision mixed \
            $([ "$forces" = smooth ] && echo --smooth) --integrators rattle rattle+rescale $INTERVAL_ROWS \
            --steps 500 --rounds 3 --json "$WORK/dhfr_openmm_settings_$forces.json" 2>&1
    done
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
