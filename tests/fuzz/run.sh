#!/usr/bin/env bash
# Builds the libFuzzer harnesses of tests/fuzz with clang and runs each for a bounded time on a copy
# of its seed corpus (the tree is never written). Prints, per harness, the executions, the coverage
# libFuzzer reports and whether it found anything; exits 1 when a harness crashed, 77 (skipped) when
# clang or libFuzzer is missing.
#
# usage: tests/fuzz/run.sh [--build DIR] [--seconds N] [--only NAME,...] [--keep DIR] [--jobs N]
#   --build DIR    build folder (default build/fuzz)
#   --seconds N    per harness (default $CDC_FUZZ_SECONDS, else 15)
#   --only NAMES   run only these harnesses (comma-separated)
#   --keep DIR     copy the grown corpora and any crash inputs to DIR (for longer runs by hand)
#   --jobs N       build jobs (default: all cores)
set -euo pipefail

HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
ROOT=$(cd "$HERE/../.." && pwd)
build="$ROOT/build/fuzz"
seconds=${CDC_FUZZ_SECONDS:-15}
only=""
keep=""
jobs=$(nproc)

while [ $# -gt 0 ]; do
  case "$1" in
    --build) build=${2:?}; shift 2 ;;
    --seconds) seconds=${2:?}; shift 2 ;;
    --only) only=${2:?}; shift 2 ;;
    --keep) keep=${2:?}; shift 2 ;;
    --jobs) jobs=${2:?}; shift 2 ;;
    -h|--help) sed -n '2,13p' "$0"; exit 0 ;;
    *) echo "fuzz: unknown option '$1'" >&2; exit 2 ;;
  esac
done

start=$(date +%s)
CC=${CDC_FUZZ_CC:-clang}
CXX=${CDC_FUZZ_CXX:-clang++}
work=$(mktemp -d "${TMPDIR:-/tmp}/cdc-fuzz-run.XXXXXX")
trap 'rm -rf "$work"' EXIT

# clang and libFuzzer (Debian: clang and libclang-rt-<version>-dev, deploy/install-deps.sh).
if ! command -v "$CXX" >/dev/null 2>&1; then
  echo "fuzz: skipped: $CXX not found (deploy/install-deps.sh installs clang)"
  exit 77
fi
printf 'extern "C" int LLVMFuzzerTestOneInput(const unsigned char*, unsigned long) { return 0; }\n' >"$work/probe.cpp"
if ! "$CXX" -fsanitize=fuzzer,address,undefined "$work/probe.cpp" -o "$work/probe" 2>"$work/probe.log"; then
  echo "fuzz: skipped: $CXX cannot link libFuzzer (-fsanitize=fuzzer); install the libclang-rt-<version>-dev of"
  echo "      the installed clang (deploy/install-deps.sh). The compiler said:"
  sed 's/^/      /' "$work/probe.log" | head -5
  exit 77
fi

# Paths relative to the tree in ccache's keys: a new build folder or worktree reuses the cache.
export CCACHE_BASEDIR=${CCACHE_BASEDIR:-$ROOT} CCACHE_NOHASHDIR=${CCACHE_NOHASHDIR:-1}
echo "fuzz: building the harnesses ($CXX, $build)"
if [ ! -f "$build/CMakeCache.txt" ]; then
  cmake -S "$HERE" -B "$build" -G Ninja -DCMAKE_C_COMPILER="$CC" -DCMAKE_CXX_COMPILER="$CXX" >"$work/configure.log" ||
    { cat "$work/configure.log"; exit 1; }
fi
cmake --build "$build" -j "$jobs" >"$work/build.log" 2>&1 || { tail -50 "$work/build.log"; exit 1; }
built=$(date +%s)

harnesses=()
for d in "$HERE"/corpus/*/; do
  h=$(basename "$d")
  if [ -n "$only" ] && [[ ",$only," != *",$h,"* ]]; then continue; fi
  harnesses+=("$h")
done

export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1}
failed=()
printf 'fuzz: %d harnesses, %s s each\n' "${#harnesses[@]}" "$seconds"
printf '%-14s %12s %10s %8s %8s %8s  %s\n' harness executions exec/s cov ft corpus result
for h in "${harnesses[@]}"; do
  mkdir -p "$work/corpus/$h" "$work/artifacts"
  cp -r "$HERE/corpus/$h/." "$work/corpus/$h/"
  status=0
  "$build/fuzz_$h" -max_total_time="$seconds" -print_final_stats=1 -timeout=10 -rss_limit_mb=2048 \
    -artifact_prefix="$work/artifacts/$h-" "$work/corpus/$h" >"$work/$h.log" 2>&1 || status=$?
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$work/$h.log" | tail -1)
  rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$work/$h.log" | tail -1)
  last=$(grep -E '^#[0-9]+.*cov: ' "$work/$h.log" | tail -1 || true)
  cov=$(sed -n 's/.* cov: \([0-9]*\).*/\1/p' <<<"$last")
  ft=$(sed -n 's/.* ft: \([0-9]*\).*/\1/p' <<<"$last")
  corp=$(sed -n 's/.* corp: \([0-9]*\).*/\1/p' <<<"$last")
  result=ok
  if [ "$status" -ne 0 ]; then
    result="FAILED (exit $status)"
    failed+=("$h")
  fi
  printf '%-14s %12s %10s %8s %8s %8s  %s\n' "$h" "${execs:-?}" "${rate:-?}" "${cov:-?}" "${ft:-?}" "${corp:-?}" \
    "$result"
  if [ "$status" -ne 0 ]; then
    grep -E -A40 'ERROR: |runtime error|==[0-9]+==' "$work/$h.log" | head -60 | sed 's/^/    /'
    mkdir -p "$build/artifacts"
    cp "$work/artifacts/$h-"* "$build/artifacts/" 2>/dev/null || true
    echo "    crash inputs: $build/artifacts/ (reproduce: $build/fuzz_$h FILE)"
  fi
done

if [ -n "$keep" ]; then
  mkdir -p "$keep"
  cp -r "$work/corpus" "$work/artifacts" "$keep/"
  echo "fuzz: grown corpora and crash inputs in $keep"
fi
end=$(date +%s)
echo "fuzz: build $((built - start)) s, fuzzing $((end - built)) s, total $((end - start)) s"
if [ ${#failed[@]} -gt 0 ]; then
  echo "fuzz: FAILED: ${failed[*]}"
  exit 1
fi
echo "fuzz: no findings"
