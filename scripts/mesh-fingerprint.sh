#!/usr/bin/env bash
# Prints a SHA-256 per written mesh file for the phantom, mickey, spheres_argmax and the knee,
# meshed at default parameters with a fixed thread count, plus a hash of each run report with its
# timings removed. Two builds that print the same lines write byte-identical meshes: this is how a
# behaviour-preserving change (a refactoring) is shown to be one.
#
#   bash scripts/mesh-fingerprint.sh [BUILD_DIR] > after.txt
#   diff before.txt after.txt        # no output: identical meshes
#
# Environment: FEMESHER_DATA_DIR (default ../shared/data), FINGERPRINT_VOLUMES (space-separated
# names among: phantom mickey spheres_argmax knee; default all four), FINGERPRINT_THREADS (2).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD="$(cd "${1:-$ROOT/build}" && pwd)"
CLI="$BUILD/bin/femesher"
DATA="${FEMESHER_DATA_DIR:-$ROOT/../shared/data}"
THREADS="${FINGERPRINT_THREADS:-2}"
VOLUMES="${FINGERPRINT_VOLUMES:-phantom mickey spheres_argmax knee}"
[ -x "$CLI" ] || { echo "mesh-fingerprint: no femesher in $BUILD/bin (build first)" >&2; exit 2; }
WORK="$(mktemp -d)"
trap 'rm -rf "$WORK"' EXIT
# Paths inside the work folder are relative: the writers record the input's path, which must not
# depend on where the data or the temporary folder are.
mkdir -p "$WORK/in"
cd "$WORK"

input_of() {
  case "$1" in
    phantom) "$CLI" phantom in/phantom.nrrd >/dev/null 2>&1; echo in/phantom.nrrd ;;
    mickey) cp "$DATA/mickey.nrrd" in/; echo in/mickey.nrrd ;;
    spheres_argmax) cp "$DATA/spheres_argmax.nrrd" in/; echo in/spheres_argmax.nrrd ;;
    knee) cp "$DATA/9135902_00m_WB01.nii.gz" in/; echo in/9135902_00m_WB01.nii.gz ;;
    *) echo "mesh-fingerprint: unknown volume '$1'" >&2; exit 2 ;;
  esac
}

for v in $VOLUMES; do
  in="$(input_of "$v")"
  out="$v"
  mkdir -p "$out"
  "$CLI" mesh "$in" --threads "$THREADS" -o "$out/m.vtu" -o "$out/m.inp" -o "$out/m.msh" \
    -o "$out/m.mesh" -o "$out/m.feb" -o "$out/m.stl" -o "$out/m.vtk" \
    --report "$out/report.json" >"$out/log.txt" 2>&1 ||
    { echo "mesh-fingerprint: meshing $v failed:" >&2; cat "$out/log.txt" >&2; exit 1; }
  for f in m.vtu m.inp m.msh m.mesh m.feb m.stl m.vtk; do
    echo "$v $f $(sha256sum <"$out/$f" | cut -d' ' -f1)"
  done
  # The report without what legitimately differs between runs (seconds, paths, version).
  python3 - "$out/report.json" "$v" <<'EOF'
import hashlib, json, sys
r = json.load(open(sys.argv[1]))
# memory_estimate holds the machine's available memory at the time of the run.
for k in ("stages", "total_seconds", "surface_mesher_seconds", "femesher_version", "memory_estimate"):
    r.pop(k, None)
r.get("input", {}).pop("path", None)
print(sys.argv[2], "report.counts+quality+fidelity",
      hashlib.sha256(json.dumps(r, sort_keys=True).encode()).hexdigest())
EOF
done
