#!/usr/bin/env bash
# Installs what is missing, builds, and runs the whole test suite.
# Tests that need ../shared (real data, the XFeat model) find it beside the
# checkout or through AG_SHARED_DIR, and skip with a message where it is absent.
set -euo pipefail
cd "$(dirname "$0")/.."
start=$(date +%s)
tools/setup.sh
built=$(date +%s)
ctest --test-dir build --output-on-failure -j "$(nproc)" --timeout 900
end=$(date +%s)
echo "test.sh: build $((built - start)) s, tests $((end - built)) s"
