#!/usr/bin/env bash
# One command from a fresh Debian 12 machine to a mesh: installs the packages, builds FEMesher and
# meshes the built-in proximal-femur phantom (`femesher phantom`; `--hip` is the clinical-size one). Outputs go to ./out/phantom/.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
bash scripts/install-deps.sh
bash scripts/build.sh
mkdir -p out/phantom
./build/bin/femesher phantom out/phantom/phantom.nrrd
./build/bin/femesher mesh out/phantom/phantom.nrrd \
  -o out/phantom/phantom.vtu -o out/phantom/phantom.inp -o out/phantom/phantom.msh \
  -o out/phantom/phantom.mesh -o out/phantom/phantom.feb -o out/phantom/phantom.stl -o out/phantom/phantom.vtk \
  --report out/phantom/report.json
echo
echo "Done. The phantom label map and its meshes are in $ROOT/out/phantom/:"
ls -l out/phantom/
