#!/usr/bin/env bash
# The GPU step's figures on whatever GPU this machine has, in under 5 minutes: the adapter's name, then
# `benchmark gpu` (GPU time per step from timestamp queries, the work the shader counted per strand-step,
# the bytes a step moves, for 2 000 × 32 guides with 20 000 followers, 10 000 × 32 and 50 000 × 32; then
# the plugin's CPU time per step with read-back every step and off), then the GPU tests (the GPU step
# against the CPU, and in the plugin) on this adapter's hardware arithmetic.
#
# Build where the code is and carry the binaries (a GPU machine may have no network):
#   cargo build --release --example benchmark
#   cargo test --no-run --test gpu
# then run `benches/gpu-device.sh` there. Arguments go to the benchmark (`--quick`: 10 000 guides at most).
set -uo pipefail
cd "$(dirname "$0")/.."
start=$(date +%s)
echo "== adapter"
nvidia-smi --query-gpu=name,driver_version,memory.total,clocks.max.sm --format=csv 2>/dev/null ||
    echo "(no nvidia-smi)"
benchmark=${BENCHMARK:-target/release/examples/benchmark}
if [ ! -x "$benchmark" ]; then
    echo "== building the benchmark (not carried)"
    cargo build --release --example benchmark || exit 1
fi
echo "== benchmark gpu"
timeout 200 "$benchmark" gpu "$@" || echo "(benchmark ended with status $?)"
echo "== the GPU tests on this adapter"
binary=$(ls -t target/debug/deps/gpu-* 2>/dev/null | grep -v '\.d$' | head -1)
if [ -n "$binary" ]; then
    timeout 90 "$binary" --test-threads 1 --nocapture step:: plugin:: 2>&1 |
        grep -E "adapter|per strand-step|RMS|test result|panicked|FAILED" || echo "(the GPU tests ended with status $?)"
else
    echo "(the GPU tests not built: cargo test --no-run --test gpu)"
fi
echo "== done in $(( $(date +%s) - start )) s"
