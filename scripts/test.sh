#!/usr/bin/env bash
# One command from a bare Debian 12 machine to the whole test suite:
#  1. Release build, every unit/golden/corpus test (ctest);
#  2. the same tests built with AddressSanitizer + UndefinedBehaviorSanitizer;
#  3. the tile cache and scheduler tests under ThreadSanitizer;
#  4. the RIB, shading-language, render and map/texture fuzzers (libFuzzer)
#     for a bounded time.
# Set UMBRA_QUICK=1 to run step 1 only.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
jobs=$(nproc)
fuzz_seconds=${UMBRA_FUZZ_SECONDS:-60}
# Each stage's wall time, so that where CI's time goes is on record.
stage_start=$SECONDS
stage() {
  [ -n "${stage_name:-}" ] && echo "-- $stage_name: $((SECONDS - stage_start)) s"
  stage_name=$1
  stage_start=$SECONDS
  [ -n "$1" ] && echo "== $1"
  return 0
}

stage "release build and tests"
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j"$jobs"
ctest --test-dir build -j"$jobs" --output-on-failure --timeout 600

if [ "${UMBRA_QUICK:-0}" = 1 ]; then stage ""; exit 0; fi

# Sanitizer builds: -O2 with line tables only (-g1) is enough for the
# sanitizers' stacks, and compiles and links faster than -g.
sanitizer_flags=(-DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -g1 -DNDEBUG"
  -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O2 -g1 -DNDEBUG" -DUMBRA_BENCHMARKS=OFF)

stage "AddressSanitizer + UndefinedBehaviorSanitizer"
cmake -S . -B build-asan -G Ninja "${sanitizer_flags[@]}" -DUMBRA_SANITIZE=address,undefined >/dev/null
cmake --build build-asan -j"$jobs"
# The Slurm test (label slurm) runs in the Release stage only: its cluster
# runs the Release umbra's jobs, and under ASan the same scripts would only
# be slower.
ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
  ctest --test-dir build-asan -j"$jobs" --output-on-failure --timeout 900 -LE slurm

stage "ThreadSanitizer (concurrent tile cache and bucket scheduler)"
cmake -S . -B build-tsan -G Ninja "${sanitizer_flags[@]}" -DUMBRA_SANITIZE=thread >/dev/null
tsan_targets=()
# The list is read whole: `grep -q` stopping at the first match made ninja
# die of SIGPIPE, and under pipefail the later targets were silently left out.
targets_list=$(cmake --build build-tsan --target help)
for t in test_shadow test_render; do
  if grep -q "^$t:" <<<"$targets_list"; then tsan_targets+=("$t"); fi
done
if [ ${#tsan_targets[@]} -gt 0 ]; then
  cmake --build build-tsan -j"$jobs" --target "${tsan_targets[@]}"
  for t in "${tsan_targets[@]}"; do
    # history_size=7: the largest per-thread history, so TSan can still
    # restore the stacks of reads made long before a report (TBB workers
    # reading the main thread's stack lost them at the default size, and
    # the suppressions could not match).
    # Each test runs in a process of its own: TBB's hand-offs are invisible
    # to TSan, so a worker's read of the main thread's stack in one test
    # and the main thread's write to the same (reused) stack address in a
    # later test looked like a race, with the worker's stack too old to
    # restore and match the TBB suppressions.
    # The image-quality studies (many single renders scored against exact
    # shadows) add ten minutes under TSan and no concurrency the others
    # lack; the Release and ASan stages run them. So do the limits tests
    # (Limits.*): each renders one pathological input in a child process,
    # adds no concurrency, and under a loaded TSan run one went past its
    # CPU limit.
    tests=$("build-tsan/bin/$t" --gtest_list_tests --gtest_filter='-OpenFloor.*:Scenes/ShadowQuality.*:Limits.*' |
      awk '/^[^ ]/ {suite = $1} /^  / {print suite $1}')
    # $jobs processes at a time (most tests keep one core busy); the first
    # failure prints its log and stops xargs starting more (exit 255).
    export t
    if ! xargs -P "$jobs" -n 1 bash -c '
        log=$(mktemp)
        if ! TSAN_OPTIONS="halt_on_error=1 history_size=7 suppressions=$PWD/tests/tsan.supp" "build-tsan/bin/$t" \
             --gtest_filter="$1" >"$log" 2>&1; then
          cat "$log"
          echo "umbra: $t $1 failed under ThreadSanitizer (above)" >&2
          rm -f "$log"
          exit 255
        fi
        rm -f "$log"' _ <<<"$tests"; then
      exit 1
    fi
    echo "$t: $(wc -w <<<"$tests") tests passed under ThreadSanitizer"
  done
fi

stage "fuzzers (${fuzz_seconds}s each)"
CC=clang CXX=clang++ cmake -S . -B build-fuzz -G Ninja "${sanitizer_flags[@]}" \
  -DUMBRA_FUZZERS=ON -DUMBRA_TESTS=OFF -DUMBRA_SANITIZE=address,undefined >/dev/null
cmake --build build-fuzz -j"$jobs" --target fuzzers
for f in build-fuzz/bin/fuzz_*; do
  # Seeds: the project's own scenes and shaders.
  work=$(mktemp -d)
  case "$(basename "$f")" in
    fuzz_rib) find scenes tests/rib_errors -name '*.rib' -size -64k -exec cp {} "$work"/ \; ;;
    fuzz_render) cp tests/fuzz/render_corpus/*.rib "$work"/ ;;
    fuzz_slc) cp shaders_dsl/*.sl tests/unit/shading/errors/*.sl "$work"/ ;;
    fuzz_maps) cp tests/fuzz/maps_corpus/*.seed "$work"/ ;;
  esac
  log="$work.log"
  # The crash report (the input, the sanitizer's stack) must reach the CI
  # log: print the whole tail on failure, only the final statistics on success.
  # A 32 MB ASan quarantine (default 256) keeps the process near 300 MB
  # instead of growing towards the 2 GB limit over a long run.
  # No leak checks here: clang 14's LeakSanitizer, stopping the render's
  # worker threads to scan them, crashes now and then ("Tracer caught
  # signal 11 ... LeakSanitizer has encountered a fatal error", on an empty
  # input), which failed the stage with nothing wrong in umbra. The g++
  # ASan stage above checks every test for leaks.
  if ! ASAN_OPTIONS=quarantine_size_mb=32:detect_leaks=0 "$f" -detect_leaks=0 -max_total_time="$fuzz_seconds" -timeout=10 -rss_limit_mb=2048 -print_final_stats=1 \
       -artifact_prefix="$work/" "$work" >"$log" 2>&1; then
    tail -n 80 "$log"
    echo "umbra: $(basename "$f") found a failing input (above)" >&2
    exit 1
  fi
  tail -n 3 "$log"
  rm -rf "$work" "$log"
done
stage ""
echo "umbra: all test stages passed in $SECONDS s"
