#!/usr/bin/env bash
# One command from a fresh Debian 12 machine to a full test run: installs the packages, builds
# FEMesher and runs every test (unit, real-data integration, real readers, CalculiX, GUI).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
bash scripts/install-deps.sh
bash scripts/build.sh
cd build
ctest --output-on-failure -j "${FEMESHER_TEST_JOBS:-2}" --timeout 1500
