#!/usr/bin/env bash
# Configures and builds umbra in Release into build/ (build/bin/umbra).
set -euo pipefail
cd "$(dirname "$0")/.."
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release "$@" >/dev/null
cmake --build build -j"$(nproc)"
